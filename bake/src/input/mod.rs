//! Inputs: asset files turned into densities on regular grids over the unit hypercube.
//!
//! # Axis and cell conventions (the one place they are written down)
//!
//! Every input lives in `[0,1]^d`. A [`Grid`] with `dims = [n0, n1, …]` splits axis `k` into `n_k`
//! equal cells; cell `(i0, i1, …)` covers `[i0/n0, (i0+1)/n0] × [i1/n1, (i1+1)/n1] × …` and is stored at
//! buffer index `i0 + n0·(i1 + n1·(i2 + …))`: **axis 0 varies fastest**. A point `p` belongs to the cell
//! `floor(p_k · n_k)` on every axis (evaluated in `f64`, clamped to the grid).
//!
//! Images: axis 0 = x (column, left to right), axis 1 = y (row, **top to bottom**), so cell `(x, y)`
//! covers `[x/W, (x+1)/W] × [y/H, (y+1)/H]` and the grid buffer is the image in its natural row-major
//! order. Volumes and BRDF grids follow the same rule with their own axes (x fastest).
//!
//! Volumes (`.vol`) and meshes (`.obj`): axis 0 = x, axis 1 = y, axis 2 = z. A `.vol` grid's cells
//! are the grid's cells (it fills the cube); a mesh is placed by `[mesh] fit` and voxelized at
//! `[mesh] resolution` with mass 1 inside, 0 outside. Details in [`crate::input`].
//!
//! BRDFs (isotropic, measured): axis 0 = θi, axis 1 = θo, axis 2 = φd = φo − φi, with
//! `(θi, θo, φd) ∈ [0, π/2] × [0, π/2] × [0, π]` mapped linearly to `[0,1]³` (φd is folded into
//! `[0, π]` by isotropy and reciprocity). The grid is `res³` cells (`[brdf] resolution`, default
//! 180); cell mass = luminance, no Jacobian. The measure, the value formula and the sampling pdf are
//! in [`crate::input::brdf`].
//!
//! # Density and color
//!
//! Pixels are decoded to linear RGB plus a linear alpha (see [`load_image`]); `Y = 0.2126 R +
//! 0.7152 G + 0.0722 B`. The [`DensityChannel`] turns a pixel into a mass and a color-to-mass ratio:
//!
//! | channel     | mass                    | ratio                 | meaning                              |
//! |-------------|-------------------------|-----------------------|--------------------------------------|
//! | `luminance` | `Y · alpha`             | `rgb / Y` (0 if Y = 0)| displayed color = mass · ratio        |
//! | `inverted`  | `max(0, 1 − Y) · alpha` | `rgb` (straight)      | dark ink on white; composited later  |
//! | `alpha`     | `alpha`                 | `rgb` (straight)      | cut-outs                             |
//!
//! Masses are not normalized here: the sampler normalizes, and [`Grid::mean_mass`] keeps the scale
//! that the run-time needs to put the luminance back (paper §6.4).

pub mod brdf;
mod grid;
mod image;
pub mod mesh;
pub mod vol;

pub use self::image::{load_image, srgb_to_linear};
pub use grid::Grid;

use crate::limits::Budget;
use std::fmt;
use std::path::{Path, PathBuf};

/// Kinds of input files. A new input format adds a variant, its extensions in [`EXTENSIONS`], and a
/// loader module; the manifest and the baker dispatch through here and nowhere else.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// PNG, JPEG (sRGB) or EXR (linear) images: 2D.
    Image,
    /// MERL isotropic BRDF (`.binary`): 3D over (θi, θo, φd).
    Merl,
    /// Cornell irregularly sampled isotropic BRDF (`.brdf`): 3D over (θi, θo, φd).
    Cornell,
    /// Mitsuba binary volume grid (`.vol`): a 3D density over the unit cube.
    Volume,
    /// Wavefront OBJ mesh (`.obj`): uniform density inside, voxelized (`[mesh]` settings).
    Mesh,
}

/// File extensions (lower case) of every input kind.
pub const EXTENSIONS: &[(&str, InputKind)] = &[
    ("png", InputKind::Image),
    ("jpg", InputKind::Image),
    ("jpeg", InputKind::Image),
    ("exr", InputKind::Image),
    ("binary", InputKind::Merl),
    ("brdf", InputKind::Cornell),
    ("vol", InputKind::Volume),
    ("obj", InputKind::Mesh),
];

impl InputKind {
    /// The kind of `path`, by extension (case-insensitive); `None` if unsupported.
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        EXTENSIONS.iter().find(|(e, _)| *e == ext).map(|(_, k)| *k)
    }

    /// Dimension of the domain of inputs of this kind.
    pub fn dim(self) -> usize {
        match self {
            InputKind::Image => 2,
            InputKind::Merl | InputKind::Cornell | InputKind::Volume | InputKind::Mesh => 3,
        }
    }

    /// Whether inputs of this kind are BRDFs (resampled to a `[brdf] resolution` grid).
    pub fn is_brdf(self) -> bool {
        matches!(self, InputKind::Merl | InputKind::Cornell)
    }

    /// Whether inputs of this kind take a `density` channel (images only: BRDFs are luminance,
    /// volumes are their values).
    pub fn has_channels(self) -> bool {
        self == InputKind::Image
    }

    /// `.png, .jpg, …`: for error messages.
    pub fn supported() -> String {
        EXTENSIONS
            .iter()
            .map(|(e, _)| format!(".{e}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Settings of how inputs are turned into grids, beyond the density channel.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Cells per axis of BRDF grids.
    pub brdf_resolution: usize,
    /// Resolution and placement of mesh grids.
    pub mesh: crate::input::mesh::voxelize::MeshOptions,
    /// Placement of `.vol` grids.
    pub volume_fit: crate::input::vol::VolFit,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            brdf_resolution: crate::input::brdf::DEFAULT_RESOLUTION,
            mesh: Default::default(),
            volume_fit: Default::default(),
        }
    }
}

/// Loads any supported input file as a density grid (default [`LoadOptions`]).
pub fn load(path: &Path, channel: DensityChannel) -> Result<Grid, InputError> {
    load_with(path, channel, &LoadOptions::default())
}

/// Loads any supported input file as a density grid, within the process's default budget
/// ([`Budget::for_process`]).
pub fn load_with(
    path: &Path,
    channel: DensityChannel,
    options: &LoadOptions,
) -> Result<Grid, InputError> {
    load_within(path, channel, options, &Budget::for_process())
}

/// Loads any supported input file as a density grid, refusing with [`InputError::Limit`] before
/// allocating when the decoded size (from the file's header or counts) exceeds `budget`.
pub fn load_within(
    path: &Path,
    channel: DensityChannel,
    options: &LoadOptions,
    budget: &Budget,
) -> Result<Grid, InputError> {
    let kind = InputKind::from_path(path);
    if kind.is_some_and(InputKind::is_brdf) && channel != DensityChannel::Luminance {
        return Err(InputError::BrdfValue {
            path: path.to_path_buf(),
            message: format!("density `{channel}` does not apply to BRDFs: their density is the luminance (remove `density`)"),
        });
    }
    if kind.is_some_and(|k| k.dim() == 3 && !k.is_brdf()) && channel != DensityChannel::Luminance {
        return Err(InputError::Density3d {
            path: path.to_path_buf(),
            channel,
        });
    }
    let res = options.brdf_resolution;
    if kind.is_some_and(InputKind::is_brdf) {
        crate::input::brdf::check_grid(path, res, budget)?;
    }
    match kind {
        Some(InputKind::Image) => self::image::load_image_within(path, channel, budget),
        Some(InputKind::Merl) => {
            let merl = crate::input::brdf::merl::Merl::read(path)?;
            crate::input::brdf::to_grid(path, res, |a, b, c| merl.eval(a, b, c))
        }
        Some(InputKind::Cornell) => {
            let lattice = crate::input::brdf::cornell::Cornell::read(path)?.lattice();
            crate::input::brdf::to_grid(path, res, |a, b, c| lattice.eval(a, b, c))
        }
        Some(InputKind::Volume) => crate::input::vol::load_within(path, options.volume_fit, budget),
        Some(InputKind::Mesh) => {
            crate::input::mesh::voxelize::load_within(path, &options.mesh, budget)
        }
        None => Err(InputError::UnsupportedExtension {
            path: path.to_path_buf(),
            ext: path
                .extension()
                .and_then(|e| e.to_str())
                .unwrap_or("")
                .to_string(),
        }),
    }
}

/// Which quantity of a pixel is the density (see the table in the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DensityChannel {
    /// `mass = Y · alpha`, `ratio = rgb / Y`.
    #[default]
    Luminance,
    /// `mass = max(0, 1 − Y) · alpha`, `ratio = rgb`: dark shapes on a white background.
    Inverted,
    /// `mass = alpha`, `ratio = rgb`.
    Alpha,
}

impl DensityChannel {
    /// The name used in manifests (`luminance`, `inverted`, `alpha`).
    pub fn name(self) -> &'static str {
        match self {
            DensityChannel::Luminance => "luminance",
            DensityChannel::Inverted => "inverted",
            DensityChannel::Alpha => "alpha",
        }
    }
}

impl fmt::Display for DensityChannel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why an input could not be turned into a density grid. Messages name the file (and the pixel
/// where one is at fault) and say how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("input file {} does not exist: check the path (relative paths are resolved from the manifest's folder)", path.display())]
    NotFound { path: PathBuf },

    #[error("cannot read input file {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    #[error("input file {} has an unsupported extension {ext:?}: supported are {} (convert the file to one of them)", path.display(), InputKind::supported())]
    UnsupportedExtension { path: PathBuf, ext: String },

    #[error("cannot decode image {}: {message}; re-export it as an ordinary 8- or 16-bit PNG or a baseline JPEG", path.display())]
    Decode { path: PathBuf, message: String },

    #[error("cannot read OpenEXR image {}: {message}; the first layer needs R, G and B channels (A optional) — re-export it as a scanline RGBA EXR", path.display())]
    Exr { path: PathBuf, message: String },

    #[error("image {} is empty ({width}x{height} pixels): give an image with at least one pixel", path.display())]
    EmptyImage {
        path: PathBuf,
        width: usize,
        height: usize,
    },

    #[error("image {}: pixel (x {x}, y {y}) channel {channel} is {value}: EXR inputs must be finite and non-negative; replace NaN, infinite and negative values (e.g. by 0) and re-export", path.display())]
    BadPixel {
        path: PathBuf,
        x: usize,
        y: usize,
        channel: &'static str,
        value: f32,
    },

    #[error("the density channel `{channel}` of {} is zero everywhere: choose another `density`", path.display())]
    NoMass {
        path: PathBuf,
        channel: DensityChannel,
    },

    #[error("image {} gives an invalid density: {message}; rescale the image's values", path.display())]
    InvalidDensity { path: PathBuf, message: String },

    #[error(transparent)]
    Brdf(#[from] crate::input::brdf::BrdfError),

    #[error("BRDF {}: {message}", path.display())]
    BrdfValue { path: PathBuf, message: String },

    #[error(transparent)]
    Volume(#[from] crate::input::vol::VolError),

    #[error(transparent)]
    Mesh(#[from] crate::input::mesh::MeshError),

    #[error("density `{channel}` does not apply to {}: a volume's density is its values, a mesh's is uniform inside (remove `density`)", path.display())]
    Density3d {
        path: PathBuf,
        channel: DensityChannel,
    },

    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),

    #[error("invalid density grid: {0}")]
    GridShape(String),

    #[error(
        "invalid density grid: cell {index} has {what} {value}: values must be finite and >= 0"
    )]
    GridValue {
        index: usize,
        what: &'static str,
        value: f32,
    },

    #[error("invalid density grid: the total mass is zero (every cell is 0): give a grid with some mass")]
    GridNoMass,
}
