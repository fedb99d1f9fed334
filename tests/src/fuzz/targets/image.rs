//! The `image` target: PNG, JPEG and OpenEXR files through our image wrapper
//! (`input::load_within` → `load_image_within`: the header's size against the budget, the image
//! crate's or the exr crate's decoder with the budget as its allocation limit, the value checks,
//! the density channel).
//!
//! Mutations know both containers. PNG: the IHDR fields (width, height, bit depth, colour type,
//! interlace), chunk lengths, chunks dropped, duplicated, swapped or cut, bytes inside a chunk —
//! then, four times in five, every chunk's CRC is recomputed so the damage reaches the decoder
//! instead of stopping at the checksum. EXR: the header's attributes are parsed and one attribute's
//! value is rewritten by its type (`box2i` windows, the channel list's pixel types and sampling,
//! compression, line order, tiles) or its size field; or an offset-table entry or a chunk's
//! `y`/size header gets a hostile value; or the version flags change (tiled, long names, deep,
//! multi-part). Plus the byte-level mutations, and one execution in 16 hands a file to the
//! decoder of another extension.

use super::{accepted, budget};
use crate::fuzz::{mutate, Case, Rng, Scratch, Target};
use otbake::input::{load_within, DensityChannel, LoadOptions};

/// Longest mutated file.
const MAX_LEN: usize = 128 << 10;

/// The PNG signature.
const PNG_MAGIC: &[u8] = b"\x89PNG\r\n\x1a\n";

/// CRC-32 (IEEE, as PNG uses it).
fn crc32(bytes: &[u8]) -> u32 {
    static TABLE: std::sync::OnceLock<[u32; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (n, e) in t.iter_mut().enumerate() {
            let mut c = n as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *e = c;
        }
        t
    });
    !bytes.iter().fold(!0u32, |c, &b| {
        table[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8)
    })
}

/// A PNG chunk's place: offset of its length field and its data length (as stored).
#[derive(Clone, Copy)]
struct Chunk {
    at: usize,
    len: usize,
}

fn png_chunks(b: &[u8]) -> Vec<Chunk> {
    let mut out = Vec::new();
    let mut at = PNG_MAGIC.len();
    while at + 12 <= b.len() {
        let len = u32::from_be_bytes(b[at..at + 4].try_into().unwrap()) as usize;
        if at + 12 + len > b.len() {
            break;
        }
        out.push(Chunk { at, len });
        at += 12 + len;
    }
    out
}

fn fix_crcs(b: &mut [u8]) {
    for c in png_chunks(b) {
        let crc = crc32(&b[c.at + 4..c.at + 8 + c.len]);
        b[c.at + 8 + c.len..c.at + 12 + c.len].copy_from_slice(&crc.to_be_bytes());
    }
}

fn mutate_png(rng: &mut Rng, b: &mut Vec<u8>) {
    let chunks = png_chunks(b);
    if chunks.is_empty() {
        return;
    }
    let c = *rng.pick(&chunks);
    match rng.below(7) {
        0 => {
            // An IHDR field (IHDR is the first chunk).
            let ihdr = chunks[0].at + 8;
            match rng.below(5) {
                0 | 1 => {
                    let at = ihdr + 4 * rng.below(2);
                    let v: u32 =
                        *rng.pick(&[0, 1, 2, 3, 7, 64, 255, 1 << 14, 20_000, 1 << 31, u32::MAX]);
                    if let Some(d) = b.get_mut(at..at + 4) {
                        d.copy_from_slice(&v.to_be_bytes());
                    }
                }
                2 => {
                    if let Some(d) = b.get_mut(ihdr + 8) {
                        *d = *rng.pick(&[1, 2, 4, 8, 16, 0, 3, 32]);
                    }
                }
                3 => {
                    if let Some(d) = b.get_mut(ihdr + 9) {
                        *d = *rng.pick(&[0, 2, 3, 4, 6, 1, 5, 7]);
                    }
                }
                _ => {
                    if let Some(d) = b.get_mut(ihdr + 10 + rng.below(3)) {
                        *d = rng.below(3) as u8;
                    }
                }
            }
        }
        1 => {
            b.drain(c.at..c.at + 12 + c.len);
        }
        2 => {
            let chunk = b[c.at..c.at + 12 + c.len].to_vec();
            let d = *rng.pick(&chunks);
            b.splice(d.at..d.at, chunk);
        }
        3 if c.len > 0 => {
            // Cut the chunk's data, keeping its length field consistent.
            let keep = rng.below(c.len);
            b.drain(c.at + 8 + keep..c.at + 8 + c.len);
            b[c.at..c.at + 4].copy_from_slice(&(keep as u32).to_be_bytes());
        }
        4 => {
            let v: u32 = *rng.pick(&[0, 1, 0x7FFF_FFFF, u32::MAX, c.len as u32 + 1]);
            b[c.at..c.at + 4].copy_from_slice(&v.to_be_bytes());
        }
        _ if c.len > 0 => {
            let at = c.at + 8 + rng.below(c.len);
            b[at] = rng.next_u64() as u8;
        }
        _ => {}
    }
}

/// An EXR header attribute: where its size field and value are, and its type.
struct Attribute {
    kind: String,
    size_at: usize,
    value: std::ops::Range<usize>,
}

fn cstr(b: &[u8], at: usize) -> Option<(String, usize)> {
    let end = at + b.get(at..)?.iter().position(|&c| c == 0)?;
    Some((String::from_utf8_lossy(&b[at..end]).into_owned(), end + 1))
}

/// The first header's attributes and where the header ends.
fn exr_attributes(b: &[u8]) -> (Vec<Attribute>, usize) {
    let mut out = Vec::new();
    let mut at = 8;
    while let Some((name, next)) = cstr(b, at) {
        if name.is_empty() {
            return (out, next);
        }
        let Some((kind, next)) = cstr(b, next) else {
            break;
        };
        let Some(size) = b.get(next..next + 4) else {
            break;
        };
        let size = i32::from_le_bytes(size.try_into().unwrap());
        let Ok(size) = usize::try_from(size) else {
            break;
        };
        let value = next + 4..next + 4 + size;
        if value.end > b.len() {
            break;
        }
        at = value.end;
        out.push(Attribute {
            kind,
            size_at: next,
            value,
        });
    }
    (out, at)
}

fn mutate_exr(rng: &mut Rng, b: &mut [u8]) {
    let (attrs, header_end) = exr_attributes(b);
    let hostile = |rng: &mut Rng| *rng.pick(&mutate::HOSTILE_I32);
    match rng.below(6) {
        0..=2 if !attrs.is_empty() => {
            let a = rng.pick(&attrs);
            let v = a.value.clone();
            match a.kind.as_str() {
                "box2i" if v.len() == 16 => {
                    let at = v.start + 4 * rng.below(4);
                    let x = if rng.one_in(2) {
                        hostile(rng)
                    } else {
                        rng.below(70) as i32 - 3
                    };
                    mutate::put(b, at, x.to_le_bytes());
                }
                "chlist" if !v.is_empty() => {
                    // Entries: name\0, pixel type i32, pLinear u8, 3 reserved, xSampling, ySampling.
                    let mut at = v.start;
                    let mut fields = Vec::new();
                    while let Some((name, next)) = cstr(b, at) {
                        if name.is_empty() || next + 16 > v.end {
                            break;
                        }
                        fields.extend([next, next + 8, next + 12]);
                        at = next + 16;
                    }
                    if !fields.is_empty() {
                        let at = *rng.pick(&fields);
                        let x = if rng.one_in(2) {
                            hostile(rng)
                        } else {
                            rng.below(4) as i32
                        };
                        mutate::put(b, at, x.to_le_bytes());
                    } else {
                        b[v.start] = rng.next_u64() as u8;
                    }
                }
                "compression" | "lineOrder" | "envmap" if !v.is_empty() => {
                    b[v.start] = rng.below(12) as u8;
                }
                "tiledesc" if v.len() == 9 => {
                    let at = v.start + 4 * rng.below(2);
                    mutate::put(b, at, hostile(rng).to_le_bytes());
                }
                _ if rng.one_in(3) => mutate::put(b, a.size_at, hostile(rng).to_le_bytes()),
                _ if !v.is_empty() => {
                    let at = v.start + rng.below(v.len());
                    b[at] = rng.next_u64() as u8;
                }
                _ => {}
            }
        }
        3 if header_end + 8 <= b.len() => {
            // An offset-table entry.
            let entries = ((b.len() - header_end) / 8).min(64);
            let at = header_end + 8 * rng.below(entries.max(1));
            let len = b.len() as u64;
            let any = rng.next_u64();
            let v: u64 = *rng.pick(&[0, 1, len, len + 1, len - 1, u64::MAX, 1 << 40, any]);
            if let Some(d) = b.get_mut(at..at + 8) {
                d.copy_from_slice(&v.to_le_bytes());
            }
        }
        4 if header_end + 8 <= b.len() => {
            // A chunk's y or data size: the first chunk follows the offsets, read from entry 0.
            let first = u64::from_le_bytes(b[header_end..header_end + 8].try_into().unwrap());
            let at = usize::try_from(first).unwrap_or(usize::MAX);
            if at.checked_add(8).is_some_and(|e| e <= b.len()) {
                let at = at + 4 * rng.below(2);
                mutate::put(b, at, hostile(rng).to_le_bytes());
            }
        }
        _ if b.len() >= 8 => {
            // Version flags: tiled 0x200, long names 0x400, deep 0x800, multi-part 0x1000.
            b[5] ^= 1 << (1 + rng.below(4));
        }
        _ => {}
    }
}

/// See the module docs.
pub struct ImageTarget;

impl Target for ImageTarget {
    fn name(&self) -> &'static str {
        "image"
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        let b = case.bytes_mut();
        for _ in 0..1 + rng.below(3) {
            let png = b.starts_with(PNG_MAGIC);
            let exr = b.starts_with(&[0x76, 0x2f, 0x31, 0x01]);
            match rng.below(3) {
                0 | 1 if png => mutate_png(rng, b),
                0 | 1 if exr => mutate_exr(rng, b),
                _ => mutate::bytes(rng, b, other.bytes(), MAX_LEN),
            }
        }
        if b.starts_with(PNG_MAGIC) && !rng.one_in(5) {
            fix_crcs(b);
        }
        b.truncate(MAX_LEN);
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        let own = case.files[0]
            .0
            .rsplit('.')
            .next()
            .unwrap_or("png")
            .to_string();
        let ext = if rng.one_in(16) {
            rng.pick(&["png", "jpg", "exr"]).to_string()
        } else {
            own
        };
        let name = format!("in.{ext}");
        let path = scratch.write(&name, case.bytes());
        let channel = *rng.pick(&[
            DensityChannel::Luminance,
            DensityChannel::Inverted,
            DensityChannel::Alpha,
        ]);
        accepted(
            load_within(&path, channel, &LoadOptions::default(), &budget()),
            &name,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_matches_the_png_iend_chunk() {
        // Every PNG ends with the IEND chunk, whose CRC is AE 42 60 82.
        assert_eq!(crc32(b"IEND"), 0xAE42_6082);
    }
}
