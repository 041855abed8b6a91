//! Values written as Python's `repr` writes them: floats for the files (the Python writer
//! used `%r`, and the files must stay byte for byte the same) and strings and float lists
//! for the readers' messages.
//!
//! Floats are written with their shortest round-trip digits (`ryu`) laid out as Python's
//! `repr` (`0.0001`, `1e-05`, `1e+16`, `1.0`), so a file reads back to the same float64
//! values.

/// Python's `repr` of a string, for error messages.
pub(crate) fn repr(s: &str) -> String {
    let quote = if s.contains('\'') && !s.contains('"') { '"' } else { '\'' };
    let mut out = String::with_capacity(s.len() + 2);
    out.push(quote);
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if c == quote => {
                out.push('\\');
                out.push(c);
            }
            c if (c as u32) < 0x20 || c as u32 == 0x7f => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push(quote);
    out
}

/// Lays out shortest round-trip digits as Python's `repr` does: `ryu_text` is ryu's text of a
/// positive finite non-zero number (`123.45`, `0.00012`, `1e-7`, `1.5e300`).
pub(crate) fn push_python_layout(out: &mut Vec<u8>, ryu_text: &[u8]) {
    let mut digits = [0u8; 48];
    let (mut n, mut point, mut exp) = (0usize, None, 0i32);
    for (i, &b) in ryu_text.iter().enumerate() {
        match b {
            b'.' => point = Some(n),
            b'e' | b'E' => {
                let e = &ryu_text[i + 1..];
                let (neg, e) = if e.first() == Some(&b'-') { (true, &e[1..]) } else { (false, e) };
                exp = e.iter().fold(0i32, |a, &d| a * 10 + i32::from(d - b'0'));
                if neg {
                    exp = -exp;
                }
                break;
            }
            d => {
                digits[n] = d;
                n += 1;
            }
        }
    }
    // The value is 0.DIGITS x 10^decpt.
    let mut decpt = point.unwrap_or(n) as i32 + exp;
    let mut lo = 0;
    while lo + 1 < n && digits[lo] == b'0' {
        lo += 1;
        decpt -= 1;
    }
    let mut hi = n;
    while hi > lo + 1 && digits[hi - 1] == b'0' {
        hi -= 1;
    }
    let d = &digits[lo..hi];
    let len = d.len() as i32;
    if -4 < decpt && decpt <= 16 {
        if decpt <= 0 {
            out.extend_from_slice(b"0.");
            out.resize(out.len() + (-decpt) as usize, b'0');
            out.extend_from_slice(d);
        } else if decpt >= len {
            out.extend_from_slice(d);
            out.resize(out.len() + (decpt - len) as usize, b'0');
            out.extend_from_slice(b".0");
        } else {
            out.extend_from_slice(&d[..decpt as usize]);
            out.push(b'.');
            out.extend_from_slice(&d[decpt as usize..]);
        }
    } else {
        out.push(d[0]);
        if len > 1 {
            out.push(b'.');
            out.extend_from_slice(&d[1..]);
        }
        let e = decpt - 1;
        out.extend_from_slice(if e < 0 { b"e-" } else { b"e+" });
        if e.abs() < 10 {
            out.push(b'0');
        }
        out.extend_from_slice(itoa::Buffer::new().format(e.abs()).as_bytes());
    }
}

/// Python's `repr(x)` of a float64: shortest digits that read back to `x`.
pub(crate) fn push_f64(out: &mut Vec<u8>, x: f64, buf: &mut ryu::Buffer) {
    if x.is_nan() {
        out.extend_from_slice(b"nan");
        return;
    }
    if x.is_sign_negative() {
        out.push(b'-');
    }
    if x.is_infinite() {
        out.extend_from_slice(b"inf");
    } else if x == 0.0 {
        out.extend_from_slice(b"0.0");
    } else {
        let text = buf.format_finite(x.abs()).as_bytes();
        // ryu's layout is Python's but for exponents (`1e-7` for `1e-07`, `1e16` for
        // `1e+16`) and for 1e-5 <= x < 1e-4, which ryu writes as `0.0000...`.
        if text.contains(&b'e') || text.starts_with(b"0.0000") {
            push_python_layout(out, text);
        } else {
            out.extend_from_slice(text);
        }
    }
}

pub(crate) fn f64_text(x: f64) -> String {
    let mut out = Vec::new();
    push_f64(&mut out, x, &mut ryu::Buffer::new());
    String::from_utf8(out).expect("ascii")
}

/// Python's list repr of floats: `[0.0, nan, 1e+300]`.
pub(crate) fn floats_text(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|&x| f64_text(x)).collect();
    format!("[{}]", items.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(x: f64) -> String {
        f64_text(x)
    }

    #[test]
    fn floats_are_laid_out_as_python_repr() {
        let cases = [
            (1.0, "1.0"),
            (-0.0, "-0.0"),
            (0.1, "0.1"),
            (0.0001, "0.0001"),
            (0.00001, "1e-05"),
            (1e15, "1000000000000000.0"),
            (1e16, "1e+16"),
            (123456.789, "123456.789"),
            (5e-324, "5e-324"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (1.5e-7, "1.5e-07"),
            (-2.0 / 3.0, "-0.6666666666666666"),
            (1e100, "1e+100"),
            (f64::INFINITY, "inf"),
        ];
        for (x, want) in cases {
            assert_eq!(text(x), want, "{x:e}");
        }
    }
}
