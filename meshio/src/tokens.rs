//! Lines split into tokens and numbers read as Python reads them, so that a file reads to
//! what the former Python reader gave and fails where it failed.
//!
//! Numbers are read with the standard library's `f64` parser (exact, and the
//! Eisel-Lemire algorithm that `fast-float` implements), accepting what Python's
//! `float()` accepts for ASCII digits, `_` between digits included. Tokens split where
//! Python's `str.split()` splits; the OBJ reader makes Unicode spaces ASCII ones first.

/// Whitespace as Python's `str.split()` sees it among ASCII characters, one table lookup.
pub(crate) fn is_space(b: u8) -> bool {
    const SPACE: [bool; 256] = {
        let mut t = [false; 256];
        let mut b = 0;
        while b < 256 {
            t[b] = b == 32 || (9 <= b && b <= 13) || (0x1c <= b && b <= 0x1f);
            b += 1;
        }
        t
    };
    SPACE[b as usize]
}

/// The whitespace-separated tokens of a line.
#[derive(Clone)]
pub(crate) struct Tokens<'a> {
    s: &'a str,
    pub(crate) i: usize,
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        let b = self.s.as_bytes();
        while self.i < b.len() && is_space(b[self.i]) {
            self.i += 1;
        }
        if self.i == b.len() {
            return None;
        }
        let start = self.i;
        while self.i < b.len() && !is_space(b[self.i]) {
            self.i += 1;
        }
        Some(&self.s[start..self.i])
    }
}

pub(crate) fn tokens(s: &str) -> Tokens<'_> {
    Tokens { s, i: 0 }
}

pub(crate) fn trim(s: &str) -> &str {
    s.trim_matches(|c: char| c.is_ascii() && is_space(c as u8))
}

/// The token with Python's `_` digit separators removed, if it has valid ones.
pub(crate) fn without_underscores(token: &str) -> Option<String> {
    let b = token.as_bytes();
    if !b.contains(&b'_') {
        return None;
    }
    let digit = |i: Option<&u8>| i.is_some_and(u8::is_ascii_digit);
    for (i, &c) in b.iter().enumerate() {
        if c == b'_' && !(i > 0 && digit(b.get(i - 1)) && digit(b.get(i + 1))) {
            return None;
        }
    }
    Some(token.replace('_', ""))
}

/// A float as Python's `float()` reads it (nan, inf, exponents, `_` between digits).
pub(crate) fn parse_f64(token: &str) -> Option<f64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

pub(crate) fn parse_i64(token: &str) -> Option<i64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

/// An optionally signed decimal integer at `b[*i..]`, advancing `i`; None if there is none
/// (or it overflows).
pub(crate) fn scan_int(b: &[u8], i: &mut usize) -> Option<i64> {
    let negative = b.get(*i) == Some(&b'-');
    if negative || b.get(*i) == Some(&b'+') {
        *i += 1;
    }
    let start = *i;
    let mut v: i64 = 0;
    while let Some(&d) = b.get(*i).filter(|d| d.is_ascii_digit()) {
        v = v.checked_mul(10)?.checked_add(i64::from(d - b'0'))?;
        *i += 1;
    }
    (*i > start).then_some(if negative { -v } else { v })
}
