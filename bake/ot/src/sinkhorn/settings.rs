//! The Sinkhorn solver's settings (a plain config struct), their checks and fingerprint, and the
//! defaults and tolerances the solver derives from them.

use super::NAME;
use crate::SolveError;

/// How the map is read off the final plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// One-to-one: each source point goes to a distinct target sample (sparse auction refinement).
    Assignment,
    /// Barycentric projection of the entropic plan: smooth, slightly contracted (by about the blur).
    Barycentric,
}

impl MapKind {
    /// The manifest's word for it ("assignment" | "barycentric").
    pub fn name(self) -> &'static str {
        match self {
            MapKind::Assignment => "assignment",
            MapKind::Barycentric => "barycentric",
        }
    }
}

/// Settings of the Sinkhorn solver (manifest `[solver] kind = "sinkhorn"`).
#[derive(Clone, Debug, PartialEq)]
pub struct SinkhornSettings {
    /// Final blur (ε = blur²) in coordinate units. `None`: `blur_spacing` × the point spacing
    /// where a typical point lives, ρ^(−1/d) for the density ρ a point sees, of the denser cloud
    /// (`point_spacing`; for a near-uniform cloud the mean spacing of its occupied volume).
    pub blur: Option<f64>,
    /// Final blur as a multiple of that point spacing, when `blur` is not given. `None`:
    /// `DEFAULT_BLUR_SPACING` for the dimension.
    pub blur_spacing: Option<f64>,
    /// Blur ratio between consecutive stages, in (0, 1).
    pub scaling: f64,
    /// Marginal error (L1, total mass 1) the final stage iterates to; earlier stages go to
    /// `STAGE_TOLERANCE` × this. Earlier stages must be converged *more* tightly: a loosely
    /// converged stage hands the next, smaller ε a potential whose error is low-frequency, which
    /// Sinkhorn at small ε removes very slowly (measured: stage tolerance 1e-2 before a final 1e-3
    /// stage left that stage stalled at 2e-3 after 2000 iterations). Default 1.5e-3 (1e-3 until
    /// D165: the 1M cow's final stage then read 1.06e-3 at iteration 33 and iterated to 43, for
    /// the same cost; with the cycles after the auction the 5K ratios stay better than before).
    /// 3e-3 was 20% faster in an early solver and gave the same 5K cost ratios, but it let the
    /// plan's rows err by up to ~600 points' worth of mass at 250K: the duck sampled with seed 0
    /// then left that solver's auction a row set its support could not match (D18). With `map =
    /// "assignment"` the final stage goes to at most 1.5e-3 whatever this says
    /// (`ASSIGNMENT_TOLERANCE`).
    pub tolerance: f64,
    /// Iterations allowed per stage. Intermediate stages that hit it go on (the next stage starts
    /// from their potentials, and the report counts them); the final stage must converge.
    pub max_iterations: u32,
    /// Truncation θ: pairs more than θ·ε above their row's and column's best are dropped (their
    /// kernel entries are below e^−θ of the best). `None`: `DEFAULT_TRUNCATE` for the dimension
    /// ([`SinkhornSettings::theta`]).
    pub truncate: Option<f64>,
    /// How the map is read off the plan.
    pub map: MapKind,
    /// `map = "assignment"` only: the auction's final ε as a fraction of the final Sinkhorn ε.
    /// The auction's matching is within n·ε_auction of the best the kernel's support allows, and
    /// short cycles then take back most of what it gave away locally (D164); each division by 4
    /// is one more auction phase. `None`: `DEFAULT_AUCTION_EPS` for the dimension (one phase). A
    /// second phase can take minutes on large inputs: its price war parks rows for augmenting
    /// paths (the 250K duck at 1/16 ran past 150 s, D161).
    pub auction_eps: Option<f64>,
}

impl Default for SinkhornSettings {
    fn default() -> Self {
        Self {
            blur: None,
            blur_spacing: None,
            scaling: 0.5,
            tolerance: 1.5e-3,
            max_iterations: 2000,
            truncate: None,
            map: MapKind::Assignment,
            auction_eps: None,
        }
    }
}

/// Revision of the solver's algorithm, part of every fingerprint (so of every map's cache key):
/// bumped whenever the same settings give different maps, so that caches from an earlier otbake
/// are rebaked rather than silently reused. 2: the auction on precomputed reduced costs and, in
/// 3D, from ε/4 (`AUCTION_START`); loose mid-stage rebuilds. 3: the final blur from the density a
/// typical point sees, cell levels as fine as the final blur in dense parts (D130, D131). 4: rows
/// past what the final kernel certifies widened by exact searches, the rest completed by sparse
/// shortest paths instead of dense ones (D144). 5: the auction in one phase from ε/4 in every
/// dimension, a phase whose bids stall parked for the paths, which read the support where it
/// certifies a row (D145). 6: local rebuilds search what moved more than θε/8, not θε/16 (D148).
/// 7: ω = 1.9 on the cell stages, a plain probe every 10 over-relaxed iterations (D150). 8: kernel
/// entries' exponentials in `f32` (the 1M cow's map moved among near-ties, D154). 9: a row's
/// K·v in four partial sums, the over-relaxation's power as exp(ω' ln x) (D155; the measured maps
/// kept every byte, but a near-tie elsewhere may not). 10: local rebuilds rescale the entries they
/// keep by a row and a column factor instead of valuing them afresh (D157; the 1M cow's map moved
/// among near-ties, the others measured kept their bytes). 11: the stages before the last end on
/// their tolerance whatever their support's drift (D161). 12: the soft c-transform carrying a
/// potential to the next stage sums its exponentials by a polynomial, not libm (D162; the
/// measured maps kept every byte, but a near-tie elsewhere may not). 13: a local rebuild searches
/// what moved since it was last searched, at (θ + τ)ε, not everything that moved since the last
/// whole build (D163). 14: short cycles after the auction, and its final ε by dimension, 1/2 in
/// 2D (D164). 15: the final tolerance 1.5e-3 by default, earlier stages still at 3e-4 (D165).
/// 16: the auction's prices start lowered away from the target's outline (D169).
/// 17: θ = 6 by default in 2D (D171). 18: lists a widened row replaced no longer count against
/// the lists' limit (D174; maps change only where that limit was reached, as the 16M cow's did).
const REVISION: u32 = 18;

impl SinkhornSettings {
    /// The truncation θ a solve in dimension `dim` uses: `truncate`, or the dimension's default.
    pub fn theta(&self, dim: usize) -> f64 {
        self.truncate.unwrap_or(DEFAULT_TRUNCATE[dim.clamp(1, 3)])
    }

    pub(crate) fn fingerprint(&self) -> String {
        format!(
            "sinkhorn(rev={REVISION},blur={:?},blur_spacing={:?},scaling={:?},tolerance={:?},max_iterations={},truncate={:?},map={},auction_eps={:?})",
            self.blur,
            self.blur_spacing,
            self.scaling,
            self.tolerance,
            self.max_iterations,
            self.truncate,
            self.map.name(),
            self.auction_eps
        )
    }

    pub(super) fn check(&self) -> Result<(), SolveError> {
        let bad = |field: &'static str, reason: &str| {
            Err(SolveError::InvalidSettings {
                solver: NAME,
                field,
                reason: reason.to_string(),
            })
        };
        if let Some(b) = self.blur {
            if !(b.is_finite() && b > 0.0) {
                return bad("blur", "must be a positive number (coordinate units)");
            }
        }
        if !self.blur_spacing.is_none_or(|b| b.is_finite() && b > 0.0) {
            return bad("blur_spacing", "must be a positive number");
        }
        if !(self.scaling > 0.0 && self.scaling < 1.0) {
            return bad(
                "scaling",
                "must be in (0, 1); 0.5 halves the blur per stage",
            );
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad(
                "tolerance",
                "must be in (0, 1) (L1 marginal error, total mass 1)",
            );
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if !self.truncate.is_none_or(|t| t.is_finite() && t >= 1.0) {
            return bad(
                "truncate",
                "must be at least 1 (8 keeps entries above e^-8; the default is 6 in 2D, 8 in 3D)",
            );
        }
        if !self.auction_eps.is_none_or(|e| e > 0.0 && e <= 1.0) {
            return bad(
                "auction_eps",
                "must be in (0, 1] (a fraction of the final Sinkhorn epsilon)",
            );
        }
        Ok(())
    }
}

/// Default final blur in point spacings, by dimension (index 1, 2, 3; 3 also for 4D). A kernel row
/// keeps the points within about √θ·blur, so the pairs per point grow like blur_spacing^d: 1.5 in
/// 2D keeps about 60 pairs per point at θ = 8, and 1.0 in 3D about 100 (1.5 in 3D kept 315, and the
/// bake of a 50K mesh volume took 4.7 times as long).
pub const DEFAULT_BLUR_SPACING: [f64; 4] = [1.5, 1.5, 1.5, 1.0];

/// Default truncation θ by dimension (index 1, 2, 3; 3 also for 4D). 8 on uniform/Gaussian → shape
/// at 5K and 50K points gave the same matchings as 12 with a third fewer pairs (D33). In 2D, 6:
/// the 250K duck 6% faster (a quarter fewer pairs, three fewer final iterations), the same cost to
/// 7 digits, the 5K shapes within 3e-5 of their cost ratios at 8 (D171); in 3D, 6 added a
/// rebuild to the 1M cow's later stages and was slower (D160).
pub const DEFAULT_TRUNCATE: [f64; 4] = [8.0, 8.0, 6.0, 8.0];

/// Default `auction_eps` by dimension (index 1, 2, 3; 3 also for 4D). With the cycles after the
/// auction, 1/2 in 2D is as close to exact at 5K points as 1/4 was without them (the duck, heart
/// and tooth within 2e-5 of their cost ratios or better) for about 40% fewer bids; in 3D 1/2 with
/// the cycles is further from exact than 1/4 without them (5K cow 1.0020 against 1.0014), and
/// 1/4 with them is nearer (1.0009) (D164).
pub const DEFAULT_AUCTION_EPS: [f64; 4] = [0.5, 0.5, 0.5, 0.25];

/// Tolerance of the stages before the last, as a fraction of `tolerance`. The marginal error of a
/// stage bounds its potentials' error poorly at long wavelengths, and the next, halved ε sees that
/// error doubled in units of ε and removes it only slowly (iterations per stage grew 93, 230, 516,
/// 536 at 50K points with a factor of 1). Coarse stages are cheap, so they go further: 3e-4 before a
/// final 1e-3 (measured at 50K: the final stage then needs 60 iterations instead of 536; and 1e-4
/// before it doubled the 250K iterations without shortening the final stage). 0.2 since the
/// default final tolerance is 1.5e-3, so that they still go to 3e-4 (D165).
pub(super) const STAGE_TOLERANCE: f64 = 0.2;

/// Loosest final marginal error the auction of `map = "assignment"` starts from, whatever
/// `tolerance` says (so with that map, a looser tolerance only loosens the earlier stages). The
/// auction starts from the plan's target potential, and a looser plan leaves prices far from the
/// matching's. Gaussian → Gaussian at 50K with blur_spacing 0.5: tolerance 1e-2 ended Sinkhorn at
/// 6.9e-3 and spent nearly all of its time in bids (five times more before the auction read
/// precomputed costs); clamped to 3e-3 the solve took a third of that time, at 1e-3 a twelfth.
/// 1.5e-3 since D165 (the auction's completion and the cycles after it finish what the plan
/// leaves: the 1M cow's bids fell from 11.1M to 10.5M, the 5K ratios stayed within 2e-4).
pub(super) const ASSIGNMENT_TOLERANCE: f64 = 1.5e-3;
