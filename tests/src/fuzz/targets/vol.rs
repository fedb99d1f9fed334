//! The `vol` target: Mitsuba `.vol` grids through `input::vol::load_within` (header peek and
//! budget check, parse, density check, `fit = "pad"` placement), and the format's promise that
//! `to_bytes(parse(b)) == b` for every file that parses.
//!
//! Mutations know the 48-byte header: the magic, version, encoding, the three resolutions and the
//! channel count get hostile integers or small consistent values (with the value array resized
//! to match, so the damage reaches the value checks), the bounding box gets special floats, and the
//! values get special floats at 4-aligned offsets.

use super::{accepted, budget};
use crate::fuzz::{mutate, Case, Rng, Scratch, Target};
use otbake::input::vol::{self, VolFile, VolFit, HEADER_BYTES};
use std::path::Path;

/// Longest mutated file (values beyond are refused by the header's count anyway).
const MAX_LEN: usize = 256 << 10;

/// See the module docs.
pub struct VolTarget;

fn i32_at(b: &[u8], at: usize) -> i32 {
    b.get(at..at + 4)
        .map_or(0, |s| i32::from_le_bytes(s.try_into().unwrap()))
}

/// Resizes the values to what the header announces, when that is small.
fn fit_values(rng: &mut Rng, b: &mut Vec<u8>) {
    if b.len() < HEADER_BYTES {
        return;
    }
    let count = [8, 12, 16, 20]
        .iter()
        .try_fold(1i64, |acc, &o| acc.checked_mul(i64::from(i32_at(b, o))))
        .unwrap_or(-1);
    if (1..=1 << 16).contains(&count) {
        let want = HEADER_BYTES + 4 * count as usize;
        while b.len() < want {
            let v = if rng.one_in(4) {
                rng.float()
            } else {
                rng.unit() as f32
            };
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.truncate(want);
    }
}

impl Target for VolTarget {
    fn name(&self) -> &'static str {
        "vol"
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        let b = case.bytes_mut();
        for _ in 0..1 + rng.below(3) {
            match rng.below(9) {
                0 => {
                    // One header integer field.
                    let at = *rng.pick(&[4usize, 8, 12, 16, 20]);
                    let v = if rng.one_in(2) {
                        *rng.pick(&mutate::HOSTILE_I32)
                    } else {
                        1 + rng.below(9) as i32
                    };
                    mutate::put(b, at, v.to_le_bytes());
                    if rng.one_in(2) {
                        fit_values(rng, b);
                    }
                }
                1 => {
                    // New small resolutions and channels, values to match.
                    for at in [8, 12, 16] {
                        mutate::put(b, at, (1 + rng.below(8) as i32).to_le_bytes());
                    }
                    let channels = if rng.one_in(4) { 1 + rng.below(3) } else { 1 };
                    mutate::put(b, 20, (channels as i32).to_le_bytes());
                    fit_values(rng, b);
                }
                2 => {
                    let at = 24 + 4 * rng.below(6);
                    mutate::put(b, at, rng.float().to_le_bytes());
                }
                3 if b.len() > HEADER_BYTES => {
                    let at = HEADER_BYTES + 4 * rng.below((b.len() - HEADER_BYTES) / 4);
                    mutate::put(b, at, rng.float().to_le_bytes());
                }
                4 if b.len() > HEADER_BYTES => {
                    // Every value zero, or one negative (a signed distance), or one NaN.
                    let at = HEADER_BYTES + 4 * rng.below((b.len() - HEADER_BYTES) / 4);
                    if rng.one_in(2) {
                        b[HEADER_BYTES..].fill(0);
                    }
                    mutate::put(b, at, [-0.25f32, f32::NAN, 0.0][rng.below(3)].to_le_bytes());
                }
                5 if b.len() >= 4 => {
                    b[rng.below(4)] = *rng.pick(b"VOLX\x00\x01\x02\x03\x04");
                }
                _ => mutate::bytes(rng, b, other.bytes(), MAX_LEN),
            }
        }
        b.truncate(MAX_LEN);
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        let bytes = case.bytes();
        if let Ok(v) = VolFile::parse(Path::new("in.vol"), bytes) {
            assert!(
                v.to_bytes() == bytes,
                "a parsed .vol does not write back its bytes"
            );
        }
        let path = scratch.write("in.vol", bytes);
        let fit = if rng.one_in(3) {
            VolFit::Pad
        } else {
            VolFit::Stretch
        };
        accepted(vol::load_within(&path, fit, &budget()), "in.vol")
    }
}
