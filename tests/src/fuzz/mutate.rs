//! Mutations shared by the targets: byte-level ones for binary formats (the targets add their
//! header-field-aware ones on top) and line- and token-level ones for text formats (TOML, OBJ,
//! Cornell), which keep most of a file's structure so the damage reaches the parsers' later checks.

use super::Rng;

/// Integers that break size and count arithmetic: zero, one, signs, powers of two at the edges of
/// `u8`/`u16`/`i32`/`u32`.
pub const HOSTILE_I32: [i32; 16] = [
    0,
    1,
    -1,
    2,
    3,
    7,
    255,
    256,
    65_535,
    65_536,
    1 << 20,
    1 << 24,
    1 << 30,
    i32::MAX,
    i32::MIN,
    -2,
];

/// Numbers as text that parsers see as edge cases: overflow of every integer width, `f64`
/// overflow and underflow, non-finite spellings, odd notations.
pub const HOSTILE_NUMBERS: [&str; 34] = [
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "0.5",
    "-0.5",
    "1e308",
    "-1e308",
    "1e-320",
    "1e999",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "255",
    "65536",
    "16777217",
    "2147483647",
    "2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999999",
    "1_000",
    "0x10",
    "1.",
    ".5",
    "3.0e",
];

/// Characters that end tokens, strings, tables or lines, and a few multi-byte ones.
pub const SPECIAL_CHARS: [&str; 20] = [
    "\"", "'", "[", "]", "[[", "]]", "=", "\n", "\r\n", "#", "\\", "\0", "{", "}", ",", "/", "é",
    "\u{feff}", "\t", "\"\"\"",
];

/// `v` as 4 little-endian bytes at `at`, if they fit.
pub fn put(bytes: &mut [u8], at: usize, v: [u8; 4]) {
    if let Some(dst) = bytes.get_mut(at..at + 4) {
        dst.copy_from_slice(&v);
    }
}

/// One byte-level mutation: bit flip, random byte, hostile 32-bit integer or special float at a
/// 4-aligned offset, insertion, deletion, duplication, truncation, or a splice from `other`.
/// The result is at most `max_len` bytes.
pub fn bytes(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8], max_len: usize) {
    let len = data.len();
    match rng.below(10) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = rng.next_u64() as u8;
        }
        2 if len >= 4 => {
            let at = rng.below(len - 3) & !3;
            put(data, at, rng.pick(&HOSTILE_I32).to_le_bytes());
        }
        3 if len >= 4 => {
            let at = rng.below(len - 3) & !3;
            put(data, at, rng.float().to_le_bytes());
        }
        4 => {
            let at = rng.below(len + 1);
            let n = 1 + rng.below(16);
            let fill: Vec<u8> = (0..n).map(|_| rng.next_u64() as u8).collect();
            data.splice(at..at, fill);
        }
        5 if len > 0 => {
            let a = rng.below(len);
            let b = (a + 1 + rng.below(64)).min(len);
            data.drain(a..b);
        }
        6 if len > 0 => {
            let a = rng.below(len);
            let b = (a + 1 + rng.below(256)).min(len);
            let chunk = data[a..b].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, chunk);
        }
        7 => data.truncate(rng.below(len + 1)),
        _ if !other.is_empty() => {
            let a = rng.below(other.len());
            let b = (a + 1 + rng.below(256)).min(other.len());
            let at = rng.below(len + 1);
            let end = (at + (b - a)).min(len);
            data.splice(at..end, other[a..b].iter().copied());
        }
        _ => {}
    }
    data.truncate(max_len);
}

/// Byte ranges of the numbers in `text`: maximal runs of digits, with a leading sign and the
/// `.`, `e`, `E` of a float.
fn numbers(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        let start = i;
        if text[i] == b'-' || text[i] == b'+' {
            i += 1;
        }
        if i < text.len() && text[i].is_ascii_digit() {
            while i < text.len()
                && (text[i].is_ascii_digit() || matches!(text[i], b'.' | b'e' | b'E'))
            {
                i += 1;
            }
            out.push((start, i));
        } else {
            i = start + 1;
        }
    }
    out
}

/// Byte ranges of whitespace-separated tokens.
fn tokens(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < text.len() {
        while i < text.len() && text[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while i < text.len() && !text[i].is_ascii_whitespace() {
            i += 1;
        }
        if i > start {
            out.push((start, i));
        }
    }
    out
}

/// Byte ranges of lines, each with its line break.
fn lines(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in text.iter().enumerate() {
        if b == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < text.len() {
        out.push((start, text.len()));
    }
    out
}

/// One text-level mutation: a number replaced by a hostile one, a token by a word of `dict` (the
/// format's keywords and values) or of `other` (another corpus file), a dictionary line inserted,
/// a line deleted, duplicated (sometimes many times), swapped or spliced in from `other`, a
/// special character inserted, or a byte-level mutation. The result is at most `max_len` bytes.
pub fn text<S: AsRef<str>>(
    rng: &mut Rng,
    data: &mut Vec<u8>,
    other: &[u8],
    dict: &[S],
    max_len: usize,
) {
    let pick_range = |rng: &mut Rng, ranges: &[(usize, usize)]| {
        (!ranges.is_empty()).then(|| ranges[rng.below(ranges.len())])
    };
    match rng.below(12) {
        0..=2 => {
            if let Some((a, b)) = pick_range(rng, &numbers(data)) {
                data.splice(a..b, rng.pick(&HOSTILE_NUMBERS).bytes());
            }
        }
        3 => {
            if let (Some((a, b)), false) = (pick_range(rng, &tokens(data)), dict.is_empty()) {
                data.splice(a..b, rng.pick(dict).as_ref().bytes());
            }
        }
        4 => {
            if let Some((a, b)) = pick_range(rng, &tokens(other)) {
                let word = other[a..b].to_vec();
                if let Some((c, d)) = pick_range(rng, &tokens(data)) {
                    data.splice(c..d, word);
                }
            }
        }
        5 if !dict.is_empty() => {
            let ls = lines(data);
            let at = pick_range(rng, &ls).map_or(0, |l| l.0);
            let mut line = rng.pick(dict).as_ref().as_bytes().to_vec();
            line.push(b'\n');
            data.splice(at..at, line);
        }
        6 => {
            if let Some((a, b)) = pick_range(rng, &lines(data)) {
                data.drain(a..b);
            }
        }
        7 => {
            if let Some((a, b)) = pick_range(rng, &lines(data)) {
                let times = if rng.one_in(8) { 1 + rng.below(200) } else { 1 };
                let line = data[a..b].to_vec();
                let copies: Vec<u8> = (0..times).flat_map(|_| line.iter().copied()).collect();
                data.splice(b..b, copies);
            }
        }
        8 => {
            let ls = lines(data);
            if let (Some(x), Some(y)) = (pick_range(rng, &ls), pick_range(rng, &ls)) {
                let (x, y) = if x.0 <= y.0 { (x, y) } else { (y, x) };
                if x.1 <= y.0 {
                    let (lx, ly) = (data[x.0..x.1].to_vec(), data[y.0..y.1].to_vec());
                    data.splice(y.0..y.1, lx);
                    data.splice(x.0..x.1, ly);
                }
            }
        }
        9 => {
            if let Some((a, b)) = pick_range(rng, &lines(other)) {
                let line = other[a..b].to_vec();
                let at = pick_range(rng, &lines(data)).map_or(0, |l| l.0);
                data.splice(at..at, line);
            }
        }
        10 => {
            let at = rng.below(data.len() + 1);
            data.splice(at..at, rng.pick(&SPECIAL_CHARS).bytes());
        }
        _ => bytes(rng, data, other, max_len),
    }
    data.truncate(max_len);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_tokens_and_lines_are_found() {
        let t = b"v 1.5 -2 3e4\nf 1/2/3 4\n";
        let n: Vec<&[u8]> = numbers(t).iter().map(|&(a, b)| &t[a..b]).collect();
        assert_eq!(
            n,
            [&b"1.5"[..], b"-2", b"3e4", b"1", b"2", b"3", b"4"].to_vec()
        );
        assert_eq!(tokens(t).len(), 7);
        assert_eq!(lines(t), vec![(0, 13), (13, 23)]);
    }
}
