//! The `[solver]` section: which solver bakes every map, and its settings. A key of another solver
//! kind is an error, never ignored.

use super::error::Locator;
use super::raw::{RawMapKind, RawSolver, SolverKind};
use super::ManifestError;
use crate::solve::{
    ExactSettings, MapKind, SinkhornSettings, SlicedMap, SlicedSettings, SolverSettings,
};
use std::ops::Range;
use toml::Spanned;

/// Validates `[solver]`; `periodic` when the inputs live on the torus (some settings are not
/// available there).
pub(super) fn solver(
    loc: &Locator<'_>,
    s: &RawSolver,
    periodic: bool,
) -> Result<SolverSettings, ManifestError> {
    let skind = *s.kind.get_ref();
    check_keys(loc, s, skind)?;
    Ok(match skind {
        SolverKind::Exact => {
            let mut e = ExactSettings::default();
            if let Some(m) = &s.max_n {
                e.max_n = *m.get_ref() as usize;
            }
            SolverSettings::Exact(e)
        }
        SolverKind::Sliced => SolverSettings::Sliced(sliced(loc, s, periodic)?),
        SolverKind::Sinkhorn => SolverSettings::Sinkhorn(sinkhorn(loc, s)?),
    })
}

/// Every key belongs to some solver kinds; a key of another kind is an error, not ignored.
fn check_keys(loc: &Locator<'_>, s: &RawSolver, skind: SolverKind) -> Result<(), ManifestError> {
    let span = |v: Option<Range<usize>>| v;
    type KeyUse<'k> = (Option<Range<usize>>, &'k str, &'k [SolverKind]);
    let keys: [KeyUse; 12] = [
        (
            span(s.iterations.as_ref().map(|v| v.span())),
            "iterations",
            &[SolverKind::Sliced],
        ),
        (
            span(s.step.as_ref().map(|v| v.span())),
            "step",
            &[SolverKind::Sliced],
        ),
        (
            span(s.seed.as_ref().map(|v| v.span())),
            "seed",
            &[SolverKind::Sliced],
        ),
        (
            span(s.max_n.as_ref().map(|v| v.span())),
            "max_n",
            &[SolverKind::Exact],
        ),
        (
            span(s.blur.as_ref().map(|v| v.span())),
            "blur",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.blur_spacing.as_ref().map(|v| v.span())),
            "blur_spacing",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.scaling.as_ref().map(|v| v.span())),
            "scaling",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.tolerance.as_ref().map(|v| v.span())),
            "tolerance",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.max_iterations.as_ref().map(|v| v.span())),
            "max_iterations",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.truncate.as_ref().map(|v| v.span())),
            "truncate",
            &[SolverKind::Sinkhorn],
        ),
        (
            span(s.map.as_ref().map(|v| v.span())),
            "map",
            &[SolverKind::Sinkhorn, SolverKind::Sliced],
        ),
        (
            span(s.auction_eps.as_ref().map(|v| v.span())),
            "auction_eps",
            &[SolverKind::Sinkhorn],
        ),
    ];
    for (span, key, kinds) in keys {
        if let Some(span) = span {
            if !kinds.contains(&skind) {
                return Err(loc.at(
                    Some(span),
                    format!(
                        "`solver.{key}` applies only to kind = \"{}\": remove it",
                        kinds[0].name()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// A number in a range, or an error at its span.
fn real(
    loc: &Locator<'_>,
    v: &Option<Spanned<f64>>,
    key: &str,
    ok: &dyn Fn(f64) -> bool,
    what: &str,
) -> Result<Option<f64>, ManifestError> {
    match v {
        None => Ok(None),
        Some(x) if ok(*x.get_ref()) => Ok(Some(*x.get_ref())),
        Some(x) => Err(loc.at(
            Some(x.span()),
            format!("`solver.{key}` = {} must be {what}", x.get_ref()),
        )),
    }
}

/// `kind = "sliced"`.
fn sliced(
    loc: &Locator<'_>,
    s: &RawSolver,
    periodic: bool,
) -> Result<SlicedSettings, ManifestError> {
    let mut sl = SlicedSettings::default();
    if let Some(it) = &s.iterations {
        if *it.get_ref() == 0 || *it.get_ref() > 100_000 {
            return Err(loc.at(
                Some(it.span()),
                "`solver.iterations` must be 1 to 100000".into(),
            ));
        }
        sl.iterations = *it.get_ref();
    }
    if let Some(seed) = &s.seed {
        sl.seed = *seed.get_ref();
    }
    if let Some(v) = real(loc, &s.step, "step", &|v| v > 0.0 && v <= 1.0, "in (0, 1]")? {
        sl.step = v;
    }
    if let Some(m) = &s.map {
        sl.map = match m.get_ref() {
            RawMapKind::Flow => SlicedMap::Flow,
            RawMapKind::Assignment if periodic => {
                return Err(loc.at(
                    Some(m.span()),
                    "`solver.map` = \"assignment\" with kind = \"sliced\" is not \
                     implemented on the torus yet (periodic inputs): remove it (the \
                     flow's map) or use kind = \"sinkhorn\", whose maps are one to one"
                        .into(),
                ))
            }
            RawMapKind::Assignment => SlicedMap::Assignment,
            RawMapKind::Barycentric => {
                return Err(loc.at(
                    Some(m.span()),
                    "`solver.map` = \"barycentric\" is Sinkhorn's: kind = \"sliced\" \
                     takes map = \"flow\" (the flow's endpoints, the default) or \
                     \"assignment\" (snapped one to one onto the input's samples)"
                        .into(),
                ))
            }
        };
    }
    Ok(sl)
}

/// `kind = "sinkhorn"`.
fn sinkhorn(loc: &Locator<'_>, s: &RawSolver) -> Result<SinkhornSettings, ManifestError> {
    let mut sk = SinkhornSettings::default();
    let pos = |v: f64| v.is_finite() && v > 0.0;
    sk.blur = real(
        loc,
        &s.blur,
        "blur",
        &pos,
        "a positive length in the unit cube (e.g. 0.002)",
    )?;
    if let Some(v) = real(
        loc,
        &s.blur_spacing,
        "blur_spacing",
        &pos,
        "a positive multiple of the point spacing",
    )? {
        sk.blur_spacing = Some(v);
    }
    if let Some(v) = real(
        loc,
        &s.scaling,
        "scaling",
        &|v| v > 0.0 && v < 1.0,
        "in (0, 1) (0.5 halves the blur per stage)",
    )? {
        sk.scaling = v;
    }
    if let Some(v) = real(
        loc,
        &s.tolerance,
        "tolerance",
        &|v| v > 0.0 && v < 1.0,
        "in (0, 1) (L1 marginal error)",
    )? {
        sk.tolerance = v;
    }
    if let Some(v) = real(
        loc,
        &s.truncate,
        "truncate",
        &|v| v.is_finite() && v >= 1.0,
        "at least 1 (default 6 in 2D, 8 in 3D)",
    )? {
        sk.truncate = Some(v);
    }
    if let Some(v) = real(
        loc,
        &s.auction_eps,
        "auction_eps",
        &|v| v > 0.0 && v <= 1.0,
        "in (0, 1] (the auction's final epsilon as a fraction of Sinkhorn's)",
    )? {
        sk.auction_eps = Some(v);
    }
    if let Some(it) = &s.max_iterations {
        if *it.get_ref() == 0 {
            return Err(loc.at(
                Some(it.span()),
                "`solver.max_iterations` must be at least 1".into(),
            ));
        }
        sk.max_iterations = *it.get_ref();
    }
    if let Some(m) = &s.map {
        sk.map = match m.get_ref() {
            RawMapKind::Assignment => MapKind::Assignment,
            RawMapKind::Barycentric => MapKind::Barycentric,
            RawMapKind::Flow => {
                return Err(loc.at(
                    Some(m.span()),
                    "`solver.map` = \"flow\" is the sliced solver's: kind = \
                     \"sinkhorn\" takes map = \"assignment\" or \"barycentric\""
                        .into(),
                ))
            }
        };
    }
    Ok(sk)
}
