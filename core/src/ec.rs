//! Entropy coding: a binary range coder with adaptive probability models.
//!
//! The coder is the carry-propagating range coder of LZMA, with 16-bit probabilities
//! estimated by two adaptive counters of different speed (fast to follow a change of
//! statistics, slow to settle on a precise value) whose mean is used. Every symbol that
//! the codec writes goes through [`Encoder`]/[`Decoder`] as binary decisions, either with
//! an adaptive [`BitModel`] or as equiprobable bypass bits.
//!
//! The decoder never fails while reading: past the end of its input it reads zero bytes
//! and remembers that it did, and [`Decoder::finish`] reports it. Callers bound every
//! count they decode, so a hostile stream costs at most as much work as its length
//! justifies.

use crate::error::Corrupt;

const PROB_BITS: u32 = 16;
const PROB_ONE: u32 = 1 << PROB_BITS;
const TOP: u32 = 1 << 24;
const FAST_RATE: u32 = 4;
const SLOW_RATE: u32 = 7;
/// Exp-Golomb prefixes longer than this cannot come from the encoder (values are < 2^32).
const MAX_EG_PREFIX: u32 = 32;

/// Adaptive probability that the next bit is 0.
#[derive(Debug, Clone, Copy)]
pub struct BitModel {
    fast: u16,
    slow: u16,
}

impl Default for BitModel {
    fn default() -> Self {
        Self { fast: (PROB_ONE / 2) as u16, slow: (PROB_ONE / 2) as u16 }
    }
}

impl BitModel {
    #[inline]
    fn p0(&self) -> u32 {
        (self.fast as u32 + self.slow as u32) >> 1
    }

    #[inline]
    fn update(&mut self, bit: bool) {
        // Both counters stay inside [2^rate - 1, 2^16 - 2^rate + 1], so p0 is never 0 or 1.
        if bit {
            self.fast -= self.fast >> FAST_RATE;
            self.slow -= self.slow >> SLOW_RATE;
        } else {
            self.fast += ((PROB_ONE - self.fast as u32) >> FAST_RATE) as u16;
            self.slow += ((PROB_ONE - self.slow as u32) >> SLOW_RATE) as u16;
        }
    }
}

/// Adaptive contexts for unsigned integers coded as Exp-Golomb (order `k`): each bit of the
/// unary prefix has its own model, the suffix bits are bypass-coded.
#[derive(Debug, Clone)]
pub struct UIntModel {
    k: u32,
    prefix: [BitModel; MAX_EG_PREFIX as usize + 1],
}

impl UIntModel {
    pub fn new(k: u32) -> Self {
        Self { k, prefix: [BitModel::default(); MAX_EG_PREFIX as usize + 1] }
    }
}

/// Adaptive contexts for signed integers: a zero flag, a sign, and the magnitude minus one.
#[derive(Debug, Clone)]
pub struct IntModel {
    zero: BitModel,
    sign: BitModel,
    magnitude: UIntModel,
}

impl IntModel {
    pub fn new(k: u32) -> Self {
        Self { zero: BitModel::default(), sign: BitModel::default(), magnitude: UIntModel::new(k) }
    }
}

/// Writes binary decisions into a byte buffer.
pub struct Encoder {
    low: u64,
    range: u32,
    cache: u8,
    cache_size: u64,
    out: Vec<u8>,
    first: bool,
}

impl Default for Encoder {
    fn default() -> Self {
        Self::new()
    }
}

impl Encoder {
    pub fn new() -> Self {
        Self { low: 0, range: u32::MAX, cache: 0, cache_size: 1, out: Vec::new(), first: true }
    }

    /// Codes `bit` with the adaptive model `m` and updates it.
    #[inline]
    pub fn bit(&mut self, m: &mut BitModel, bit: bool) {
        let bound = (self.range >> PROB_BITS) * m.p0();
        if bit {
            self.low += bound as u64;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        m.update(bit);
        self.normalize();
    }

    /// Codes the low `n` bits of `value` (most significant first) with probability 1/2 each.
    pub fn bypass(&mut self, value: u32, n: u32) {
        for i in (0..n).rev() {
            self.range >>= 1;
            if (value >> i) & 1 == 1 {
                self.low += self.range as u64;
            }
            self.normalize();
        }
    }

    /// Codes an unsigned integer as adaptive Exp-Golomb.
    pub fn uint(&mut self, m: &mut UIntModel, value: u32) {
        let v = value as u64 + (1u64 << m.k);
        let nbits = 64 - v.leading_zeros(); // >= k + 1
        let prefix = nbits - 1 - m.k;
        for i in 0..prefix {
            self.bit(&mut m.prefix[i as usize], true);
        }
        self.bit(&mut m.prefix[prefix as usize], false);
        let suffix_bits = nbits - 1;
        let suffix = v & ((1u64 << suffix_bits) - 1);
        // Suffix may exceed 32 bits only for value near u32::MAX with k > 0; split it.
        if suffix_bits > 16 {
            self.bypass((suffix >> 16) as u32, suffix_bits - 16);
            self.bypass((suffix & 0xFFFF) as u32, 16);
        } else {
            self.bypass(suffix as u32, suffix_bits);
        }
    }

    /// Codes a signed integer (|value| < 2^31) as zero flag, sign and magnitude.
    pub fn int(&mut self, m: &mut IntModel, value: i32) {
        self.bit(&mut m.zero, value != 0);
        if value != 0 {
            self.bit(&mut m.sign, value < 0);
            self.uint(&mut m.magnitude, value.unsigned_abs() - 1);
        }
    }

    #[inline]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    fn shift_low(&mut self) {
        if (self.low as u32) < 0xFF00_0000 || (self.low >> 32) != 0 {
            let carry = (self.low >> 32) as u8;
            let mut temp = self.cache;
            loop {
                // The very first byte of an LZMA range coder is always zero; it is not stored.
                if !self.first {
                    self.out.push(temp.wrapping_add(carry));
                }
                self.first = false;
                temp = 0xFF;
                self.cache_size -= 1;
                if self.cache_size == 0 {
                    break;
                }
            }
            self.cache = ((self.low >> 24) & 0xFF) as u8;
        }
        self.cache_size += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    /// Flushes the coder and returns the bytes.
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        self.out
    }
}

/// Reads binary decisions written by [`Encoder`].
pub struct Decoder<'a> {
    data: &'a [u8],
    pos: usize,
    range: u32,
    code: u32,
    overrun: usize,
    corrupt: bool,
}

impl<'a> Decoder<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        let mut d = Self { data, pos: 0, range: u32::MAX, code: 0, overrun: 0, corrupt: false };
        for _ in 0..4 {
            d.code = (d.code << 8) | d.next_byte() as u32;
        }
        d
    }

    #[inline]
    fn next_byte(&mut self) -> u8 {
        match self.data.get(self.pos) {
            Some(&b) => {
                self.pos += 1;
                b
            }
            None => {
                self.overrun += 1;
                0
            }
        }
    }

    #[inline]
    fn normalize(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | self.next_byte() as u32;
        }
    }

    #[inline]
    pub fn bit(&mut self, m: &mut BitModel) -> bool {
        let bound = (self.range >> PROB_BITS) * m.p0();
        let bit = if self.code < bound {
            self.range = bound;
            false
        } else {
            self.code -= bound;
            self.range -= bound;
            true
        };
        m.update(bit);
        self.normalize();
        bit
    }

    pub fn bypass(&mut self, n: u32) -> u32 {
        let mut v = 0u32;
        for _ in 0..n {
            self.range >>= 1;
            let bit = self.code >= self.range;
            if bit {
                self.code -= self.range;
            }
            v = (v << 1) | bit as u32;
            self.normalize();
        }
        v
    }

    /// Decodes an adaptive Exp-Golomb integer. A prefix that no encoder could write marks
    /// the stream corrupt and yields 0.
    pub fn uint(&mut self, m: &mut UIntModel) -> u32 {
        let mut prefix = 0u32;
        while self.bit(&mut m.prefix[prefix as usize]) {
            prefix += 1;
            if prefix + m.k > MAX_EG_PREFIX {
                self.corrupt = true;
                return 0;
            }
        }
        let suffix_bits = prefix + m.k;
        let suffix = if suffix_bits > 16 {
            ((self.bypass(suffix_bits - 16) as u64) << 16) | self.bypass(16) as u64
        } else {
            self.bypass(suffix_bits) as u64
        };
        let v = (1u64 << suffix_bits) + suffix - (1u64 << m.k);
        u32::try_from(v).unwrap_or_else(|_| {
            self.corrupt = true;
            0
        })
    }

    pub fn int(&mut self, m: &mut IntModel) -> i32 {
        if !self.bit(&mut m.zero) {
            return 0;
        }
        let negative = self.bit(&mut m.sign);
        let magnitude = self.uint(&mut m.magnitude) as i64 + 1;
        if magnitude > i32::MAX as i64 {
            self.corrupt = true;
            return 0;
        }
        if negative { -(magnitude as i32) } else { magnitude as i32 }
    }

    /// Bytes consumed so far (a bound on the work a caller may still justify).
    #[cfg(test)]
    pub fn position(&self) -> usize {
        self.pos
    }

    /// `Err` with a reason if the decoder read past its input or met an impossible code.
    pub fn finish(&self) -> Result<(), Corrupt> {
        if self.corrupt {
            Err("impossible entropy-coded value".into())
        } else if self.overrun > 4 {
            Err("entropy-coded data ends early".into())
        } else {
            Ok(())
        }
    }

    /// True once the decoder has read far past its input: continuing only produces garbage.
    pub fn exhausted(&self) -> bool {
        self.overrun > 4 || self.corrupt
    }
}

/// One interface over the encoder and the decoder, so that a coder's traversal and
/// predictions are written once and cannot drift apart: the encoder codes and returns the
/// value it is given, the decoder ignores it and returns what it reads.
pub trait Side {
    fn bit(&mut self, m: &mut BitModel, v: bool) -> bool;
    fn uint(&mut self, m: &mut UIntModel, v: u32) -> u32;
    fn int(&mut self, m: &mut IntModel, v: i32) -> i32;
    fn bypass(&mut self, v: u32, n: u32) -> u32;
    /// True once the decoder only produces garbage; stops every loop.
    fn failed(&self) -> bool;
}

/// The encoding [`Side`], over an encoder that the caller finishes.
pub struct EncSide<'e>(pub &'e mut Encoder);

impl Side for EncSide<'_> {
    fn bit(&mut self, m: &mut BitModel, v: bool) -> bool {
        self.0.bit(m, v);
        v
    }
    fn uint(&mut self, m: &mut UIntModel, v: u32) -> u32 {
        self.0.uint(m, v);
        v
    }
    fn int(&mut self, m: &mut IntModel, v: i32) -> i32 {
        self.0.int(m, v);
        v
    }
    fn bypass(&mut self, v: u32, n: u32) -> u32 {
        self.0.bypass(v, n);
        v
    }
    fn failed(&self) -> bool {
        false
    }
}

/// The decoding [`Side`], over a decoder that the caller finishes.
pub struct DecSide<'d, 'a>(pub &'d mut Decoder<'a>);

impl Side for DecSide<'_, '_> {
    fn bit(&mut self, m: &mut BitModel, _: bool) -> bool {
        self.0.bit(m)
    }
    fn uint(&mut self, m: &mut UIntModel, _: u32) -> u32 {
        self.0.uint(m)
    }
    fn int(&mut self, m: &mut IntModel, _: i32) -> i32 {
        self.0.int(m)
    }
    fn bypass(&mut self, _: u32, n: u32) -> u32 {
        self.0.bypass(n)
    }
    fn failed(&self) -> bool {
        self.0.exhausted()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> u32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 33) as u32
    }

    #[test]
    fn round_trip_of_mixed_symbols() {
        let mut seed = 7u64;
        let bits: Vec<bool> = (0..5000).map(|i| lcg(&mut seed) % 10 < if i < 2500 { 1 } else { 8 }).collect();
        let uints: Vec<u32> = (0..2000).map(|i| if i == 0 { u32::MAX } else { lcg(&mut seed) >> (lcg(&mut seed) % 32) }).collect();
        let ints: Vec<i32> = (0..2000).map(|_| (lcg(&mut seed) as i32) >> (lcg(&mut seed) % 31 + 1)).collect();
        let raws: Vec<u32> = (0..500).map(|_| lcg(&mut seed) & 0xFFF).collect();

        let mut e = Encoder::new();
        let (mut bm, mut um, mut im) = (BitModel::default(), UIntModel::new(2), IntModel::new(0));
        for &b in &bits { e.bit(&mut bm, b); }
        for &u in &uints { e.uint(&mut um, u); }
        for &i in &ints { e.int(&mut im, i); }
        for &r in &raws { e.bypass(r, 12); }
        let data = e.finish();

        let mut d = Decoder::new(&data);
        let (mut bm, mut um, mut im) = (BitModel::default(), UIntModel::new(2), IntModel::new(0));
        assert!(bits.iter().all(|&b| d.bit(&mut bm) == b));
        assert!(uints.iter().all(|&u| d.uint(&mut um) == u));
        assert!(ints.iter().all(|&i| d.int(&mut im) == i));
        assert!(raws.iter().all(|&r| d.bypass(12) == r));
        assert_eq!(d.finish(), Ok(()));
        assert!(d.position() <= data.len());
    }

    #[test]
    fn skewed_bits_compress_below_their_entropy_bound_plus_overhead() {
        // 10000 bits with P(1) = 0.05 carry about 2864 bits of information.
        let mut seed = 3u64;
        let mut e = Encoder::new();
        let mut m = BitModel::default();
        for _ in 0..10000 {
            e.bit(&mut m, lcg(&mut seed) % 100 < 5);
        }
        let n = e.finish().len();
        assert!(n < 2864 / 8 + 40, "{n} bytes");
    }

    #[test]
    fn decoding_garbage_or_nothing_never_panics_and_is_flagged() {
        let mut d = Decoder::new(&[]);
        let mut um = UIntModel::new(0);
        for _ in 0..100 {
            d.uint(&mut um);
        }
        assert!(d.finish().is_err());
        let garbage = [0xFFu8; 64];
        let mut d = Decoder::new(&garbage);
        let mut im = IntModel::new(0);
        for _ in 0..1000 {
            d.int(&mut im);
        }
        assert!(d.finish().is_err());
    }
}
