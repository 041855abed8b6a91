//! The syntax of the container and the payloads in one place: every unit, field, width, code
//! and limit that `docs/bitstream.md` lists for the sequence header (§2), the frame unit (§3),
//! the intra and predicted payloads (§4, §4b) and the texture unit payload (§11), as named
//! constants and as one table of fields per structure, in stream order.
//!
//! The writers and readers ([`bitstream`](super::bitstream), [`payload`](super::payload),
//! [`texture_payload`](super::texture_payload), [`resync`](super::resync), the decoder) take
//! their codes, limits and offsets from here. `web/src/stream/syntax.js` mirrors this module
//! name for name; the tests below walk the tables against `docs/bitstream.md` and check that
//! the writers lay the fields out where the tables put them, and `web/test/syntax.test.js`
//! checks the JavaScript mirror against this file and the document.
//!
//! What the entropy-coded blocks hold (base mesh, motion, refresh, coefficients, UV atlas) is
//! their coders' business and is not declared here.

// The whole syntax is declared, also the entries that only the tests (against the document and
// the writers) and the JavaScript mirror read, and the limits other modules keep under their
// own names (`model::face_allowance`, which the tests check against these).
#![allow(dead_code)]

/// The type of one element of a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ty {
    U8,
    U16,
    U32,
    I32,
    F64,
    /// Two `u8`s (a numerator and a denominator).
    U8Pair,
    /// Raw bytes: a block whose length a length field gives.
    Bytes,
}

impl Ty {
    /// Bytes per element (1 for raw bytes).
    pub const fn width(self) -> usize {
        match self {
            Ty::U8 | Ty::Bytes => 1,
            Ty::U16 | Ty::U8Pair => 2,
            Ty::U32 | Ty::I32 => 4,
            Ty::F64 => 8,
        }
    }

    /// The type's name as `docs/bitstream.md` writes it.
    pub const fn text(self) -> &'static str {
        match self {
            Ty::U8 => "u8",
            Ty::U16 => "u16",
            Ty::U32 => "u32",
            Ty::I32 => "i32",
            Ty::F64 => "f64",
            Ty::U8Pair => "(u8, u8)",
            Ty::Bytes => "bytes",
        }
    }
}

/// How many elements a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Count {
    /// A fixed number.
    N(usize),
    /// One per subdivision iteration (`S`, the header's `subdiv_iterations`).
    S,
    /// As many bytes as the length field before it says; the symbol is the document's
    /// name for that length (`L`, `B`, ...).
    Len(&'static str),
}

/// One field of a structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    pub name: &'static str,
    pub ty: Ty,
    pub count: Count,
    /// Present only when the predicted payload's `mode` has [`MODE_REFRESH`] set.
    pub optional: bool,
}

const fn f(name: &'static str, ty: Ty, count: Count) -> Field {
    Field { name, ty, count, optional: false }
}

const fn opt(name: &'static str, ty: Ty, count: Count) -> Field {
    Field { name, ty, count, optional: true }
}

use Count::{Len, N, S};
use Ty::{Bytes, U16, U32, U8Pair, F64, I32, U8};

// ---- Container (§2, §3) ----

/// The first four bytes of every stream.
pub const MAGIC: &[u8; 4] = b"DMSH";
/// Format version (§10). Version 5 added the predicted payload's refresh block and `mode` bits.
pub const VERSION: u8 = 5;

/// Unit type of an intra frame unit.
pub const FRAME_INTRA: u8 = 0;
/// Unit type of a predicted frame unit.
pub const FRAME_PREDICTED: u8 = 1;
/// Unit type of a texture unit: it follows the frame unit it belongs to (§3, §11).
pub const TEXTURE_UNIT: u8 = 2;

/// Subdivision iterations the format allows (each multiplies the face count by four).
pub const MAX_SUBDIV: u32 = 6;
/// `schemes` codes.
pub const SCHEME_MIDPOINT: u8 = 0;
pub const SCHEME_LOOP: u8 = 1;
/// Bit depth of the position grid (`bits`) and of the base mesh positions (`base_bits`,
/// which is also at most `bits`).
pub const POSITION_BITS_MIN: u32 = 8;
pub const POSITION_BITS_MAX: u32 = 20;
/// `components`: the normal only, or all of (n, t, b).
pub const COMPONENTS_NORMAL: u8 = 1;
pub const COMPONENTS_ALL: u8 = 3;
/// The value of the flag bytes `per_valence` and `aq` when on (0 is off, other values invalid).
pub const FLAG_ON: u8 = 1;
/// Smallest lifting update weight denominator.
pub const UPDATE_DEN_MIN: u8 = 1;

/// The sequence header (§2), in stream order.
pub const HEADER: &[Field] = &[
    f("magic", U8, N(4)),
    f("version", U8, N(1)),
    f("frame_count", U32, N(1)),
    f("origin", F64, N(3)),
    f("step", F64, N(1)),
    f("bits", U8, N(1)),
    f("base_bits", U8, N(1)),
    f("subdiv_iterations", U8, N(1)),
    f("schemes", U8, S),
    f("per_valence", U8, N(1)),
    f("update", U8Pair, S),
    f("components", U8, N(1)),
    f("aq", U8, N(1)),
    f("aq_alpha", F64, N(1)),
    f("aq_delta", F64, N(1)),
    f("aq_h", F64, N(1)),
    f("header_crc", U32, N(1)),
];

/// Offset of `version` in the header; range errors found after the CRC report it (§2, note 2).
pub const HEADER_VERSION_AT: usize = 4;
/// Offset of `frame_count`; a count the stream has no room for is reported there.
pub const HEADER_FRAME_COUNT_AT: usize = 5;
/// Header length: `HEADER_LEN + HEADER_LEN_PER_ITERATION * S` bytes, CRC included.
pub const HEADER_LEN: usize = 75;
pub const HEADER_LEN_PER_ITERATION: usize = 3;

/// A frame unit, and a texture unit of the same layout (§3).
pub const FRAME_UNIT: &[Field] = &[
    f("frame_type", U8, N(1)),
    f("length", U32, N(1)),
    f("payload", Bytes, Len("L")),
    f("crc", U32, N(1)),
];

/// Offset of a unit's `length` field and of its payload.
pub const UNIT_LENGTH_AT: usize = 1;
pub const UNIT_PAYLOAD_AT: usize = 5;
/// Bytes of a unit besides its payload: type, length, CRC.
pub const UNIT_OVERHEAD: usize = 9;

// ---- Frame payloads (§4, §4b) ----

/// Displacement quantization parameter range.
pub const QP_MIN: i32 = -24;
pub const QP_MAX: i32 = 63;

/// The intra payload (§4).
pub const INTRA_PAYLOAD: &[Field] = &[
    f("qp", I32, N(1)),
    f("base_len", U32, N(1)),
    f("base_block", Bytes, Len("B")),
    f("coef_len", U32, N(1)),
    f("coef_block", Bytes, Len("C")),
];

/// Predicted payload `mode` bit 0: the coefficient block holds differences from the
/// reference's quantized coefficients.
pub const MODE_COEFFICIENT_DIFFERENCES: u8 = 1;
/// Predicted payload `mode` bit 1: a refresh block follows.
pub const MODE_REFRESH: u8 = 2;
/// Largest valid `mode`.
pub const MODE_MAX: u8 = 3;

/// The predicted payload (§4b); the optional fields are there with [`MODE_REFRESH`].
pub const PREDICTED_PAYLOAD: &[Field] = &[
    f("reference_distance", U32, N(1)),
    f("qp", I32, N(1)),
    f("motion_len", U32, N(1)),
    f("motion_block", Bytes, Len("M")),
    f("mode", U8, N(1)),
    opt("refresh_len", U32, N(1)),
    opt("refresh_block", Bytes, Len("R")),
    f("coef_len", U32, N(1)),
    f("coef_block", Bytes, Len("C")),
];

/// The face allowance of a frame whose payload has L bytes (§9, `model::face_allowance`):
/// `clamp(FACE_ALLOWANCE_PER_BYTE * L, FACE_ALLOWANCE_MIN, FACE_ALLOWANCE_MAX)` base faces
/// times `4^S`.
pub const FACE_ALLOWANCE_PER_BYTE: usize = 512;
pub const FACE_ALLOWANCE_MIN: usize = 1 << 20;
pub const FACE_ALLOWANCE_MAX: usize = 1 << 23;

// ---- Texture unit payload (§11) ----

/// Version of the texture unit payload layout.
pub const TEXTURE_PAYLOAD_VERSION: u8 = 1;
/// Texture video codecs, by the `codec` code the payload signals.
pub const TEXTURE_CODEC_HEVC: u8 = 0;
pub const TEXTURE_CODEC_AV1: u8 = 1;
pub const TEXTURE_CODECS: [&str; 2] = ["hevc", "av1"];
/// The atlas side's bounds (texels, each even).
pub const MIN_SIDE: u16 = 16;
pub const MAX_SIDE: u16 = 16384;
/// UV quantization bits: UV = q / (2^uv_bits - 1).
pub const UV_BITS_MIN: u8 = 1;
pub const UV_BITS_MAX: u8 = 16;
/// Fewest frames in a texture group.
pub const TEXTURE_FRAMES_MIN: u32 = 1;

/// The texture unit payload (§11).
pub const TEXTURE_PAYLOAD: &[Field] = &[
    f("version", U8, N(1)),
    f("codec", U8, N(1)),
    f("width", U16, N(1)),
    f("height", U16, N(1)),
    f("uv_bits", U8, N(1)),
    f("frames", U32, N(1)),
    f("atlas_len", U32, N(1)),
    f("atlas_block", Bytes, Len("A")),
    f("video_len", U32, N(1)),
    f("video_block", Bytes, Len("V")),
];

/// Bytes of the texture payload's fixed fields, before `atlas_len`.
pub const TEXTURE_FIXED: usize = 11;

/// The header's length for `s` subdivision iterations.
pub const fn header_len(s: usize) -> usize {
    HEADER_LEN + HEADER_LEN_PER_ITERATION * s
}

/// A field's size in bytes, with `s` subdivision iterations; None for a block.
pub const fn size(field: &Field, s: usize) -> Option<usize> {
    match field.count {
        N(n) => Some(n * field.ty.width()),
        S => Some(s * field.ty.width()),
        Len(_) => None,
    }
}

/// A field's offset in its structure, with `s` subdivision iterations, for a stream whose
/// blocks are `lens` bytes (by symbol) and whose optional fields are `with_optional` present.
pub fn offset(fields: &[Field], name: &str, s: usize, lens: &dyn Fn(&str) -> usize, with_optional: bool) -> Option<usize> {
    let mut at = 0;
    for field in fields {
        if field.name == name {
            return Some(at);
        }
        if field.optional && !with_optional {
            continue;
        }
        at += match field.count {
            Len(sym) => lens(sym),
            _ => size(field, s).expect("fixed size"),
        };
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::grid::{Grid, BITS_RANGE};
    use crate::residual::quantize::{AqParams, QP_RANGE};
    use crate::residual::subdivide::Scheme;
    use crate::residual::transform::Lifting;
    use crate::stream::bitstream::{self, FrameType, SequenceHeader, Unit};
    use crate::stream::payload::Payload;
    use crate::stream::texture_payload::TexturePayload;

    /// The document's notation for a field's type, size and offset.
    fn type_text(field: &Field) -> String {
        match (field.ty, field.count) {
            (Bytes, _) | (_, N(1)) => field.ty.text().to_string(),
            (ty, N(n)) => format!("{}[{n}]", ty.text()),
            (ty, S) => format!("{}[S]", ty.text()),
            (ty, Len(sym)) => format!("{}[{sym}]", ty.text()),
        }
    }

    fn size_text(field: &Field) -> String {
        match field.count {
            N(n) => (n * field.ty.width()).to_string(),
            S if field.ty.width() == 1 => "S".into(),
            S => format!("{}S", field.ty.width()),
            Len(sym) => sym.into(),
        }
    }

    /// A linear expression `constant + k*S + symbols`, as the document writes offsets.
    fn offset_text(fields: &[Field], index: usize, with_optional: bool) -> String {
        let (mut constant, mut k, mut syms) = (0, 0, Vec::new());
        for field in &fields[..index] {
            if field.optional && !with_optional {
                continue;
            }
            match field.count {
                N(n) => constant += n * field.ty.width(),
                S => k += field.ty.width(),
                Len(sym) => syms.push(sym),
            }
        }
        let mut text = constant.to_string();
        match k {
            0 => {}
            1 => text += "+S",
            k => text += &format!("+{k}S"),
        }
        for sym in syms {
            text += &format!("+{sym}");
        }
        text
    }

    /// The offset column for row `index`: with an optional field before an unconditional row,
    /// "without (with)".
    fn doc_offset(fields: &[Field], index: usize) -> String {
        let optional_before = fields[..index].iter().any(|f| f.optional);
        if optional_before && !fields[index].optional {
            format!("{} ({})", offset_text(fields, index, false), offset_text(fields, index, true))
        } else {
            offset_text(fields, index, true)
        }
    }

    /// The rows (offset, size, type, name) of the first table after the heading `heading`.
    fn doc_table(doc: &str, heading: &str) -> Vec<[String; 4]> {
        let start = doc.find(&format!("\n{heading}\n")).unwrap_or_else(|| panic!("no heading {heading:?} in docs/bitstream.md"));
        let mut lines = doc[start + 1..].lines().skip(1).skip_while(|l| !l.starts_with('|'));
        let cells = |line: &str| -> Vec<String> {
            let line = line.trim().trim_start_matches('|').trim_end_matches('|');
            let mut out = vec![String::new()];
            let mut prev = ' ';
            for c in line.chars() {
                if c == '|' && prev != '\\' {
                    out.push(String::new());
                } else {
                    out.last_mut().unwrap().push(c);
                }
                prev = c;
            }
            out.into_iter().map(|c| c.trim().to_string()).collect()
        };
        let head = cells(lines.next().expect("table head"));
        let col = |name: &str| head.iter().position(|h| h == name).unwrap_or_else(|| panic!("{heading}: no column {name}"));
        let (o, s, t, n) = (col("Offset"), col("Size"), col("Type"), col("Name"));
        lines
            .skip(1)
            .take_while(|l| l.starts_with('|'))
            .map(|l| {
                let c = cells(l);
                let clean = |x: &str| x.replace(' ', "");
                [clean(&c[o]), clean(&c[s]), c[t].clone(), c[n].trim_matches('`').to_string()]
            })
            .collect()
    }

    const SECTIONS: [(&str, &[Field]); 5] = [
        ("## 2. Sequence header", HEADER),
        ("## 3. Frame units", FRAME_UNIT),
        ("## 4. Intra payload", INTRA_PAYLOAD),
        ("## 4b. Predicted payload", PREDICTED_PAYLOAD),
        ("## 11. Texture unit payload", TEXTURE_PAYLOAD),
    ];

    #[test]
    fn the_tables_are_the_documents() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/bitstream.md");
        let doc = std::fs::read_to_string(path).expect("docs/bitstream.md");
        assert!(doc.starts_with(&format!("# The dynmesh bitstream (format version {VERSION})")));
        for (heading, fields) in SECTIONS {
            let rows = doc_table(&doc, heading);
            let documented: Vec<&str> = rows.iter().map(|r| r[3].as_str()).collect();
            let declared: Vec<&str> = fields.iter().map(|f| f.name).collect();
            assert_eq!(documented, declared, "{heading}: field names and order");
            for (i, (row, field)) in rows.iter().zip(fields).enumerate() {
                let ours = [doc_offset(fields, i).replace(' ', ""), size_text(field), type_text(field), field.name.to_string()];
                assert_eq!(row, &ours, "{heading}: field {} (offset, size, type, name)", field.name);
            }
        }
        let s = doc.find("**Header length** is ").expect("header length sentence");
        let expect = format!("**Header length** is {HEADER_LEN} + {HEADER_LEN_PER_ITERATION}S");
        assert!(doc[s..].starts_with(&expect), "{}", &doc[s..s + 40]);
    }

    #[test]
    fn the_named_offsets_and_lengths_follow_the_tables() {
        let none = |_: &str| 0;
        for s in 0..=MAX_SUBDIV as usize {
            let crc = offset(HEADER, "header_crc", s, &none, true).unwrap();
            assert_eq!(header_len(s), crc + 4);
        }
        assert_eq!(offset(HEADER, "version", 0, &none, true), Some(HEADER_VERSION_AT));
        assert_eq!(offset(HEADER, "frame_count", 0, &none, true), Some(HEADER_FRAME_COUNT_AT));
        assert_eq!(offset(FRAME_UNIT, "length", 0, &none, true), Some(UNIT_LENGTH_AT));
        assert_eq!(offset(FRAME_UNIT, "payload", 0, &none, true), Some(UNIT_PAYLOAD_AT));
        assert_eq!(offset(FRAME_UNIT, "crc", 0, &none, true), Some(UNIT_OVERHEAD - 4));
        assert_eq!(offset(TEXTURE_PAYLOAD, "atlas_len", 0, &none, true), Some(TEXTURE_FIXED));
        assert_eq!(MAGIC.len(), size(&HEADER[0], 0).unwrap());
        assert_eq!(TEXTURE_CODECS[TEXTURE_CODEC_HEVC as usize], "hevc");
        assert_eq!(TEXTURE_CODECS[TEXTURE_CODEC_AV1 as usize], "av1");
        assert_eq!(FrameType::Intra as u8, FRAME_INTRA);
        assert_eq!(FrameType::Predicted as u8, FRAME_PREDICTED);
        // Limits other modules keep in their own names (the encoder checks its options with them).
        assert_eq!(BITS_RANGE, POSITION_BITS_MIN..=POSITION_BITS_MAX);
        assert_eq!(QP_RANGE, QP_MIN..=QP_MAX);
        for bytes in [0, 1, 2047, 2048, 4096, 16383, 16384, 16385, usize::MAX / 2] {
            let ours = bytes.saturating_mul(FACE_ALLOWANCE_PER_BYTE).clamp(FACE_ALLOWANCE_MIN, FACE_ALLOWANCE_MAX);
            assert_eq!(crate::model::face_allowance(bytes), ours, "{bytes} bytes");
        }
    }

    /// The little-endian value of `field` (one element) at `at`.
    fn value_at(data: &[u8], at: usize, ty: Ty) -> f64 {
        let b = |n: usize| &data[at..at + n];
        match ty {
            U8 | U8Pair | Bytes => data[at] as f64,
            U16 => u16::from_le_bytes(b(2).try_into().unwrap()) as f64,
            U32 => u32::from_le_bytes(b(4).try_into().unwrap()) as f64,
            I32 => i32::from_le_bytes(b(4).try_into().unwrap()) as f64,
            F64 => f64::from_le_bytes(b(8).try_into().unwrap()),
        }
    }

    /// Checks that the writer put each of `expected`'s fields (first element) where the table says.
    fn check_layout(what: &str, fields: &[Field], data: &[u8], s: usize, lens: &dyn Fn(&str) -> usize, optional: bool, expected: &[(&str, f64)]) {
        let mut total = 0;
        for field in fields.iter().filter(|f| optional || !f.optional) {
            total += match field.count {
                Len(sym) => lens(sym),
                _ => size(field, s).unwrap(),
            };
        }
        assert_eq!(data.len(), total, "{what}: length");
        for &(name, value) in expected {
            let field = fields.iter().find(|f| f.name == name).unwrap();
            let at = offset(fields, name, s, lens, optional).unwrap();
            assert_eq!(value_at(data, at, field.ty), value, "{what}: {name} at {at}");
        }
    }

    #[test]
    fn the_writers_lay_the_fields_out_as_the_tables_say() {
        let header = SequenceHeader {
            frame_count: 7,
            grid: Grid { origin: [1.5, -2.0, 0.25], step: 0.01, bits: 12 },
            base_bits: 10,
            schemes: vec![Scheme::Midpoint, Scheme::Loop, Scheme::Loop],
            lifting: Lifting { update: vec![(63, 80), (21, 20), (7, 5)], per_valence: true },
            components: 3,
            aq: Some(AqParams { alpha: 1.25, delta: 0.25, h: 6.0 }),
        };
        let bytes = bitstream::write_header(&header);
        let none = |_: &str| 0;
        let crc = crc32fast::hash(&bytes[..bytes.len() - 4]) as f64;
        let expected = [
            ("magic", b'D' as f64),
            ("version", VERSION as f64),
            ("frame_count", 7.0),
            ("origin", 1.5),
            ("step", 0.01),
            ("bits", 12.0),
            ("base_bits", 10.0),
            ("subdiv_iterations", 3.0),
            ("schemes", SCHEME_MIDPOINT as f64),
            ("per_valence", FLAG_ON as f64),
            ("update", 63.0),
            ("components", COMPONENTS_ALL as f64),
            ("aq", FLAG_ON as f64),
            ("aq_alpha", 1.25),
            ("aq_delta", 0.25),
            ("aq_h", 6.0),
            ("header_crc", crc),
        ];
        assert_eq!(expected.map(|e| e.0).as_slice(), HEADER.iter().map(|f| f.name).collect::<Vec<_>>().as_slice());
        check_layout("header", HEADER, &bytes, 3, &none, true, &expected);
        let at = offset(HEADER, "schemes", 3, &none, true).unwrap();
        assert_eq!(&bytes[at..at + 3], &[SCHEME_MIDPOINT, SCHEME_LOOP, SCHEME_LOOP]);

        let unit = bitstream::write_texture_unit(b"texture");
        let lens = |_: &str| 7;
        check_layout("unit", FRAME_UNIT, &unit, 0, &lens, true, &[("frame_type", TEXTURE_UNIT as f64), ("length", 7.0), ("payload", b't' as f64)]);
        let unit = bitstream::write_unit(FrameType::Predicted, b"motion!");
        check_layout("unit", FRAME_UNIT, &unit, 0, &lens, true, &[("frame_type", FRAME_PREDICTED as f64)]);

        let block_lens = |sym: &str| match sym {
            "B" | "M" => 3,
            "R" => 2,
            _ => 5,
        };
        let p = Payload { reference_distance: 4, qp: -7, base: &[1, 2, 3], refresh: &[], coefficients_predicted: false, coefficients: &[9; 5] };
        let intra = p.to_bytes(FrameType::Intra);
        let expected = [("qp", -7.0), ("base_len", 3.0), ("base_block", 1.0), ("coef_len", 5.0), ("coef_block", 9.0)];
        check_layout("intra payload", INTRA_PAYLOAD, &intra, 0, &block_lens, false, &expected);
        let unit = Unit { frame_type: FrameType::Intra, payload: &intra, offset: 0, texture: None };
        assert_eq!(Payload::read(&unit, 0).unwrap().0, Payload { reference_distance: 0, ..p.clone() });

        let predicted = p.to_bytes(FrameType::Predicted);
        let mut expected = vec![("reference_distance", 4.0), ("qp", -7.0), ("motion_len", 3.0), ("motion_block", 1.0), ("mode", 0.0)];
        expected.extend([("coef_len", 5.0), ("coef_block", 9.0)]);
        check_layout("predicted payload", PREDICTED_PAYLOAD, &predicted, 0, &block_lens, false, &expected);
        let refreshed = Payload { refresh: &[6, 6], coefficients_predicted: true, ..p.clone() };
        let bytes = refreshed.to_bytes(FrameType::Predicted);
        expected[4].1 = (MODE_COEFFICIENT_DIFFERENCES | MODE_REFRESH) as f64;
        expected.extend([("refresh_len", 2.0), ("refresh_block", 6.0)]);
        check_layout("refreshed payload", PREDICTED_PAYLOAD, &bytes, 0, &block_lens, true, &expected);
        let unit = Unit { frame_type: FrameType::Predicted, payload: &bytes, offset: 0, texture: None };
        assert_eq!(Payload::read(&unit, 4).unwrap().0, refreshed);

        let t = TexturePayload { codec: TEXTURE_CODEC_AV1, width: 1024, height: 512, uv_bits: 12, frames: 3, atlas: vec![4; 3], video: vec![8; 5] };
        let bytes = t.to_bytes();
        let lens = |sym: &str| if sym == "A" { 3 } else { 5 };
        let expected = [
            ("version", TEXTURE_PAYLOAD_VERSION as f64),
            ("codec", TEXTURE_CODEC_AV1 as f64),
            ("width", 1024.0),
            ("height", 512.0),
            ("uv_bits", 12.0),
            ("frames", 3.0),
            ("atlas_len", 3.0),
            ("atlas_block", 4.0),
            ("video_len", 5.0),
            ("video_block", 8.0),
        ];
        check_layout("texture payload", TEXTURE_PAYLOAD, &bytes, 0, &lens, true, &expected);
        assert_eq!(TexturePayload::read(&bytes), Ok(t));
    }
}
