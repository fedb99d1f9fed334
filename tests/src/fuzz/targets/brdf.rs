//! The `merl` and `cornell` targets: measured BRDF files through `input::load_within` (budget
//! check, parse, resampling to a small grid).
//!
//! MERL files have one valid size, 35 MB (three `f64` planes of 90 × 90 × 180); there is none in
//! the shared data, so the full-size seed is tabulated from an analytic BRDF when the campaign
//! starts (not committed), and the committed seeds are small: headers, truncations, wrong
//! dimensions. One execution in 20 000 takes the full-size seed (header fields, special values at
//! 8-aligned offsets, lengths off by a value); the rest exercise the header and length checks.
//!
//! Cornell files are text: seeds are real files cut after a few records and hand-made edge
//! cases; mutations are text-level with the format's numbers (the 31 wavelengths, angles at and
//! past π/2). Every execution parses; one in 128 also builds the 33³ interpolation lattice and
//! resamples it (a few milliseconds, so not every time).

use super::accepted;
use crate::fuzz::{mutate, Case, Rng, Scratch, Target};
use otbake::input::brdf::{cornell::Cornell, merl, Analytic};
use otbake::input::{load_within, DensityChannel, LoadOptions};
use otbake::limits::Budget;
use std::path::Path;

/// The MERL target's budget: a full file (35 MB) is decoded into another 35 MB.
const MERL_BUDGET: u64 = 256 << 20;

/// Grid resolutions the targets resample to (small: the resampling loop is not what is fuzzed).
const RESOLUTIONS: [usize; 5] = [1, 2, 3, 4, 6];

fn channel(rng: &mut Rng) -> DensityChannel {
    if rng.one_in(16) {
        DensityChannel::Alpha
    } else {
        DensityChannel::Luminance
    }
}

fn options(rng: &mut Rng) -> LoadOptions {
    LoadOptions {
        brdf_resolution: *rng.pick(&RESOLUTIONS),
        ..LoadOptions::default()
    }
}

/// See the module docs.
pub struct MerlTarget;

impl Target for MerlTarget {
    fn name(&self) -> &'static str {
        "merl"
    }

    fn seeds(&self, corpus: &Path) -> Vec<Case> {
        let mut seeds = crate::fuzz::files_of(&corpus.join(self.name()));
        let plastic = Analytic {
            diffuse: [0.4, 0.2, 0.1],
            specular: [0.3, 0.3, 0.3],
            exponent: 30.0,
        };
        let full = merl::Merl::from_fn(|a, b, c| plastic.eval(a, b, c)).to_bytes();
        seeds.push(Case::single("full.binary", full));
        seeds
    }

    fn pick(&self, rng: &mut Rng, corpus: &[Case]) -> usize {
        let full = corpus.len() - 1;
        if rng.one_in(20_000) {
            full
        } else {
            rng.below(full.max(1))
        }
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        let b = case.bytes_mut();
        for _ in 0..1 + rng.below(3) {
            match rng.below(6) {
                0 => {
                    let at = 4 * rng.below(3);
                    let v = if rng.one_in(2) {
                        *rng.pick(&mutate::HOSTILE_I32)
                    } else {
                        *rng.pick(&[90, 180, 360, 45])
                    };
                    mutate::put(b, at, v.to_le_bytes());
                }
                1 | 2 if b.len() >= 20 => {
                    let at = 12 + 8 * rng.below((b.len() - 12) / 8);
                    let v = *rng.pick(&[
                        f64::NAN,
                        -1.0,
                        -0.0,
                        f64::INFINITY,
                        f64::MAX,
                        1e300,
                        f64::MIN_POSITIVE / 4.0,
                        0.0,
                    ]);
                    if let Some(dst) = b.get_mut(at..at + 8) {
                        dst.copy_from_slice(&v.to_le_bytes());
                    }
                }
                3 => {
                    if rng.one_in(2) {
                        b.truncate(b.len().saturating_sub(8 * rng.below(3)));
                    } else {
                        b.extend_from_slice(&[0; 8][..1 + rng.below(8)]);
                    }
                }
                _ if b.len() < 1 << 20 => mutate::bytes(rng, b, other.bytes(), 1 << 20),
                _ => {}
            }
        }
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        let path = scratch.write("in.binary", case.bytes());
        let budget = Budget::command_line(MERL_BUDGET);
        accepted(
            load_within(&path, channel(rng), &options(rng), &budget),
            "in.binary",
        )
    }

    fn memory_cap(&self) -> usize {
        2 * MERL_BUDGET as usize
    }
}

/// Longest mutated Cornell file.
const CORNELL_MAX_LEN: usize = 48 << 10;

/// Cornell numbers and fragments: the wavelength count and list, angles at the domain's edges.
const CORNELL_DICT: &[&str] = &[
    "31",
    "30",
    "32",
    "400",
    "410",
    "700",
    "710",
    "0",
    "1.5707963",
    "1.5717963",
    "1.6",
    "3.14159265",
    "-3.14159265",
    "6.2831853",
    "1e308",
    "-0.001",
    "# comment",
    "400 410 420 430 440 450 460 470 480 490 500 510 520 530 540 550 560 570 580 590 600 610 620 630 640 650 660 670 680 690 700",
    "0.1 0 0.1 3.14159 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5 0.5",
];

/// See the module docs.
pub struct CornellTarget;

impl Target for CornellTarget {
    fn name(&self) -> &'static str {
        "cornell"
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, other: &Case) {
        for _ in 0..1 + rng.below(3) {
            mutate::text(
                rng,
                case.bytes_mut(),
                other.bytes(),
                CORNELL_DICT,
                CORNELL_MAX_LEN,
            );
        }
    }

    fn execute(&self, rng: &mut Rng, case: &Case, scratch: &Scratch) -> bool {
        let text = String::from_utf8_lossy(case.bytes());
        let parsed = Cornell::parse(Path::new("in.brdf"), &text);
        if let Err(e) = &parsed {
            let msg = e.to_string();
            assert!(msg.contains("in.brdf:"), "no file and line in {msg}");
        }
        if !rng.one_in(128) {
            return parsed.is_ok();
        }
        let path = scratch.write("in.brdf", case.bytes());
        accepted(
            load_within(&path, channel(rng), &options(rng), &super::budget()),
            "in.brdf",
        )
    }
}
