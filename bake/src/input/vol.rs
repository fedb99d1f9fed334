//! Mitsuba's binary volume grid format (`.vol`), read and written byte for byte.
//!
//! Layout (little-endian; Mitsuba 0.6 `GridDataSource`, Mitsuba 3 `VolumeGrid`):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 3 | `VOL` |
//! | 3 | 1 | version, 3 |
//! | 4 | 4 | `int32` encoding: 1 = float32 (2 = float16, 3 = uint8, 4 = quantized directions) |
//! | 8 | 12 | `int32` `nx`, `ny`, `nz` |
//! | 20 | 4 | `int32` channels |
//! | 24 | 24 | 6 × `float32` bounding box: `xmin ymin zmin xmax ymax zmax` |
//! | 48 | `4 · nx·ny·nz·channels` | `float32` values, `data[((z·ny + y)·nx + x)·channels + c]` |
//!
//! Only float32 grids are read (the encoding Mitsuba writes and its tutorials use); the other
//! encodings are refused with an error that says so. [`VolFile`] keeps every header field and every
//! value's bits, so `write(read(bytes)) == bytes` for any valid file, including its bounding box and
//! any non-density values: validating values as a density is a separate step ([`VolFile::to_grid`]).
//!
//! As a density input, a 1-channel grid's cell `(x, y, z)` becomes the [`Grid`] cell with axis 0 =
//! x, axis 1 = y, axis 2 = z (x fastest in both, so the buffer is the file's value order), covering
//! `[x/nx, (x+1)/nx] × [y/ny, (y+1)/ny] × [z/nz, (z+1)/nz]`: by default **the grid fills the unit
//! cube**, axis by axis ([`VolFit::Stretch`]); the header's bounding box does not place it (a map
//! lives in `[0,1]³`, whatever the volume's world coordinates). With `[volume] fit = "pad"`
//! ([`VolFit::Pad`]) a grid of cubic cells is padded with empty cells to a cube and centered, so it
//! keeps its proportions (the box only checks that the cells are cubic).

use crate::input::{Grid, InputError};
use crate::limits::{product, Budget};
use std::path::{Path, PathBuf};

/// Bytes before the values.
pub const HEADER_BYTES: usize = 48;
/// The only version there is.
pub const VERSION: u8 = 3;
/// Encoding code of float32 values.
pub const ENCODING_F32: i32 = 1;
/// Most cells a grid may have (2^30: 4 GiB of values), so sizes never overflow.
pub const MAX_CELLS: u64 = 1 << 30;

/// Why a `.vol` file could not be read as a volume, or as a density. Every message names the file
/// and the byte offset of the field or value at fault, and how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum VolError {
    #[error("cannot read volume {}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("volume {} at byte offset {offset}: {message}", path.display())]
    Format {
        path: PathBuf,
        offset: usize,
        message: String,
    },
}

/// A Mitsuba `.vol` grid, every field as stored.
#[derive(Clone, PartialEq)]
pub struct VolFile {
    /// Cells along x, y, z.
    pub dims: [usize; 3],
    /// Values per cell.
    pub channels: usize,
    /// `xmin ymin zmin xmax ymax zmax`, as stored (any bits).
    pub bbox: [f32; 6],
    /// `nx·ny·nz·channels` values in file order (x fastest, channels interleaved), as stored.
    pub data: Vec<f32>,
}

impl std::fmt::Debug for VolFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "VolFile({:?} × {} channels, bbox {:?})",
            self.dims, self.channels, self.bbox
        )
    }
}

fn i32_at(bytes: &[u8], offset: usize) -> i32 {
    i32::from_le_bytes(bytes[offset..offset + 4].try_into().expect("4 bytes"))
}

fn f32_at(bytes: &[u8], offset: usize) -> f32 {
    f32::from_le_bytes(bytes[offset..offset + 4].try_into().expect("4 bytes"))
}

impl VolFile {
    /// A single-channel grid with the unit cube as its bounding box.
    pub fn density(dims: [usize; 3], data: Vec<f32>) -> Self {
        VolFile {
            dims,
            channels: 1,
            bbox: [0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            data,
        }
    }

    /// Reads and parses a `.vol` file.
    pub fn read(path: &Path) -> Result<Self, VolError> {
        let bytes = std::fs::read(path).map_err(|source| VolError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(path, &bytes)
    }

    /// Parses `.vol` bytes (`path` is only named in errors). Checks the magic, version, encoding,
    /// positive sizes and channel count, and that the file holds exactly the values its header
    /// announces; values are not checked (see [`VolFile::to_grid`]).
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Self, VolError> {
        let err = |offset: usize, message: String| VolError::Format {
            path: path.to_path_buf(),
            offset,
            message,
        };
        if bytes.len() < HEADER_BYTES {
            return Err(err(
                bytes.len(),
                format!(
                    "the file ends after {} bytes, inside the {HEADER_BYTES}-byte header: it is truncated or not a Mitsuba .vol grid",
                    bytes.len()
                ),
            ));
        }
        if &bytes[0..3] != b"VOL" {
            return Err(err(
                0,
                format!(
                    "the file starts with {:?}, not \"VOL\": it is not a Mitsuba binary volume (convert it, e.g. with Mitsuba's VolumeGrid.write)",
                    String::from_utf8_lossy(&bytes[0..3])
                ),
            ));
        }
        if bytes[3] != VERSION {
            return Err(err(
                3,
                format!(
                    "version {} is not supported: only version {VERSION} exists; re-save the grid with Mitsuba",
                    bytes[3]
                ),
            ));
        }
        let encoding = i32_at(bytes, 4);
        if encoding != ENCODING_F32 {
            let name = match encoding {
                2 => "float16",
                3 => "uint8",
                4 => "quantized directions",
                _ => "unknown",
            };
            return Err(err(
                4,
                format!("encoding {encoding} ({name}) is not supported: re-save the grid as float32 (encoding 1)"),
            ));
        }
        let mut dims = [0usize; 3];
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let v = i32_at(bytes, 8 + 4 * k);
            if v <= 0 {
                return Err(err(
                    8 + 4 * k,
                    format!("the {axis} resolution is {v}: every axis needs at least one cell"),
                ));
            }
            dims[k] = v as usize;
        }
        let channels = i32_at(bytes, 20);
        if channels <= 0 {
            return Err(err(
                20,
                format!("the channel count is {channels}: a grid needs at least one channel"),
            ));
        }
        let channels = channels as usize;
        // Saturating: three int32 sizes and a channel count overflow u64 (2^124), and a wrapped
        // product could match a short file.
        let values = product(&[
            dims[0] as u64,
            dims[1] as u64,
            dims[2] as u64,
            channels as u64,
        ]);
        if values > MAX_CELLS {
            let total = if values == u64::MAX {
                "at least 2^64".to_string()
            } else {
                values.to_string()
            };
            return Err(err(
                8,
                format!(
                    "{}×{}×{} cells × {channels} channels = {total} values is more than the {MAX_CELLS} supported: downsample the grid",
                    dims[0], dims[1], dims[2]
                ),
            ));
        }
        let expected = HEADER_BYTES + 4 * values as usize;
        if bytes.len() != expected {
            let (offset, what) = if bytes.len() < expected {
                (bytes.len(), "the file is truncated")
            } else {
                (expected, "the file has bytes after the last value")
            };
            return Err(err(
                offset,
                format!(
                    "{what}: a {}×{}×{} grid of {channels} channel(s) is {expected} bytes ({HEADER_BYTES}-byte header + 4 bytes per value), but the file has {}; check the header's resolution and channel count",
                    dims[0], dims[1], dims[2],
                    bytes.len()
                ),
            ));
        }
        let mut bbox = [0f32; 6];
        for (k, b) in bbox.iter_mut().enumerate() {
            *b = f32_at(bytes, 24 + 4 * k);
        }
        let data = bytes[HEADER_BYTES..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        Ok(VolFile {
            dims,
            channels,
            bbox,
            data,
        })
    }

    /// The file's bytes. Panics only if `data` does not hold `nx·ny·nz·channels` values or a size
    /// exceeds `i32` (a `VolFile` from [`VolFile::parse`] never does).
    pub fn to_bytes(&self) -> Vec<u8> {
        let values = self.dims.iter().product::<usize>() * self.channels;
        assert_eq!(self.data.len(), values, "one value per cell and channel");
        let mut out = Vec::with_capacity(HEADER_BYTES + 4 * values);
        out.extend_from_slice(b"VOL");
        out.push(VERSION);
        out.extend_from_slice(&ENCODING_F32.to_le_bytes());
        for &d in self.dims.iter().chain([&self.channels]) {
            let d = i32::try_from(d).expect("sizes fit in int32");
            out.extend_from_slice(&d.to_le_bytes());
        }
        for b in &self.bbox {
            out.extend_from_slice(&b.to_le_bytes());
        }
        for v in &self.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), crate::fsio::IoError> {
        crate::fsio::write_atomic(path, &self.to_bytes())
    }

    /// The grid as a density input (see the module docs for the placement): one channel, every value
    /// finite and `>= 0`, some value positive. Errors name the byte offset of the first bad value
    /// and its cell.
    pub fn to_grid(&self, path: &Path) -> Result<Grid, VolError> {
        let err = |offset: usize, message: String| VolError::Format {
            path: path.to_path_buf(),
            offset,
            message,
        };
        if self.channels != 1 {
            return Err(err(
                20,
                format!(
                    "the grid has {} channels: a density input needs exactly 1 (a scalar density per cell); extract the density channel",
                    self.channels
                ),
            ));
        }
        if let Some(i) = self.data.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            let [nx, ny, _] = self.dims;
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            let v = self.data[i];
            let hint = if v < 0.0 {
                "a density is an amount of matter per cell (smoke, fog, a solid's occupancy), never \
                 below 0. If this grid is a signed distance (negative inside a surface), convert it: \
                 1 where the distance is < 0 and 0 elsewhere (or a smooth band, clamp(-d / w, 0, 1) \
                 for a width w), or bake the surface as an .obj mesh instead; if it is a density \
                 with noise below 0, clamp those values to 0"
            } else {
                "replace NaN and infinite values by finite densities (e.g. 0 for empty cells) and re-save the grid"
            };
            return Err(err(
                HEADER_BYTES + 4 * i,
                format!(
                    "cell (x {x}, y {y}, z {z}) is {v}: densities must be finite and >= 0; {hint}"
                ),
            ));
        }
        if self.data.iter().all(|&v| v == 0.0) {
            return Err(err(
                HEADER_BYTES,
                "every value is 0: a density input needs some mass".into(),
            ));
        }
        Grid::new(self.dims.to_vec(), self.data.clone(), Vec::new()).map_err(|e| {
            // Unreachable after the checks above; kept as an error rather than a panic.
            err(HEADER_BYTES, e.to_string())
        })
    }
}

/// How a `.vol` grid is placed in the unit cube (`[volume] fit` in the manifest).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VolFit {
    /// The grid fills the cube axis by axis (cells become boxes of `1/nx × 1/ny × 1/nz`).
    #[default]
    Stretch,
    /// The grid is padded with empty cells to `N³`, `N` its largest resolution, and centered
    /// (`(N − n)/2` cells before, rounded down), so its proportions are kept. Needs cubic cells: the
    /// header's bounding box divided by the resolution must give the same cell size on every axis
    /// (within 1%).
    Pad,
}

/// Largest relative difference between cell sizes that [`VolFit::Pad`] accepts.
pub const PAD_TOLERANCE: f64 = 0.01;

impl VolFile {
    /// `to_grid`, then the placement of `fit`.
    pub fn to_placed_grid(&self, path: &Path, fit: VolFit) -> Result<Grid, VolError> {
        let grid = self.to_grid(path)?;
        if fit == VolFit::Stretch {
            return Ok(grid);
        }
        let cells: Vec<f64> = (0..3)
            .map(|k| (f64::from(self.bbox[k + 3]) - f64::from(self.bbox[k])) / self.dims[k] as f64)
            .collect();
        let (lo, hi) = cells
            .iter()
            .fold((f64::INFINITY, 0f64), |(a, b), &c| (a.min(c), b.max(c)));
        if !(lo.is_finite() && lo > 0.0 && hi <= lo * (1.0 + PAD_TOLERANCE)) {
            return Err(VolError::Format {
                path: path.to_path_buf(),
                offset: 24,
                message: format!(
                    "`volume.fit = \"pad\"` needs cubic cells, but the bounding box {:?} over {:?} cells gives cell sizes {cells:?}; use fit = \"stretch\" or fix the bounding box",
                    self.bbox, self.dims
                ),
            });
        }
        let n = *self.dims.iter().max().expect("three axes");
        let start = self.dims.map(|d| (n - d) / 2);
        let [nx, ny, nz] = self.dims;
        let mut mass = vec![0f32; n * n * n];
        for z in 0..nz {
            for y in 0..ny {
                let src = (z * ny + y) * nx;
                let dst = ((z + start[2]) * n + y + start[1]) * n + start[0];
                mass[dst..dst + nx].copy_from_slice(&grid.mass[src..src + nx]);
            }
        }
        Grid::new(vec![n; 3], mass, Vec::new()).map_err(|e| VolError::Format {
            path: path.to_path_buf(),
            offset: HEADER_BYTES,
            message: e.to_string(),
        })
    }
}

/// Loads a `.vol` file as a density input placed by `fit`, within the process's default budget.
pub fn load(path: &Path, fit: VolFit) -> Result<Grid, InputError> {
    load_within(path, fit, &Budget::for_process())
}

/// [`load`], refusing before reading the values a grid whose header announces more than `budget`
/// holds: the file's bytes, its values, the grid's copy and, for `fit = "pad"`, the padded cube.
pub fn load_within(path: &Path, fit: VolFit, budget: &Budget) -> Result<Grid, InputError> {
    if let Some((dims, channels)) = peek_header(path) {
        let values = product(&[dims[0], dims[1], dims[2], channels]);
        let side = dims.iter().copied().max().unwrap_or(0);
        let padded = match fit {
            VolFit::Stretch => 0,
            VolFit::Pad => product(&[side, side, side, 4 * 2]),
        };
        let needed = product(&[values, 4 * 3]).saturating_add(padded);
        budget.check(
            needed,
            || {
                format!(
                    "volume {}: {}×{}×{} cells × {channels} channel(s)",
                    path.display(),
                    dims[0],
                    dims[1],
                    dims[2]
                )
            },
            "downsample the grid",
        )?;
    }
    Ok(VolFile::read(path)?.to_placed_grid(path, fit)?)
}

/// The resolution and channel count of a `.vol` header, if the file starts with one (anything
/// else is left to [`VolFile::parse`] to explain).
fn peek_header(path: &Path) -> Option<([u64; 3], u64)> {
    use std::io::Read;
    let mut head = [0u8; HEADER_BYTES];
    std::fs::File::open(path).ok()?.read_exact(&mut head).ok()?;
    if &head[0..3] != b"VOL" {
        return None;
    }
    let v = |k: usize| u64::try_from(i32_at(&head, k)).ok().filter(|&v| v > 0);
    Some(([v(8)?, v(12)?, v(16)?], v(20)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> VolFile {
        VolFile {
            dims: [3, 2, 4],
            channels: 1,
            bbox: [-1.0, 0.5, 2.0, 3.0, 4.5, 6.25],
            data: (0..24).map(|i| i as f32 * 0.25).collect(),
        }
    }

    #[test]
    fn bytes_follow_the_documented_layout_and_round_trip() {
        let v = sample();
        let b = v.to_bytes();
        assert_eq!(b.len(), HEADER_BYTES + 24 * 4);
        assert_eq!(&b[..4], b"VOL\x03");
        assert_eq!(i32_at(&b, 4), 1);
        assert_eq!([i32_at(&b, 8), i32_at(&b, 12), i32_at(&b, 16)], [3, 2, 4]);
        assert_eq!(i32_at(&b, 20), 1);
        assert_eq!(f32_at(&b, 24 + 20), 6.25);
        // Value of cell (x 2, y 1, z 3) sits at ((3·2 + 1)·3 + 2) = 23.
        assert_eq!(f32_at(&b, HEADER_BYTES + 4 * 23), 23.0 * 0.25);
        let back = VolFile::parse(Path::new("t.vol"), &b).unwrap();
        assert_eq!(back, v);
        assert_eq!(back.to_bytes(), b);
        // Odd bits (NaN payloads, negative zero, several channels) survive too.
        let odd = VolFile {
            dims: [1, 1, 2],
            channels: 2,
            bbox: [f32::NAN, -0.0, f32::INFINITY, 1.0, 1.0, 1.0],
            data: vec![
                f32::from_bits(0x7fc0_1234),
                -0.0,
                f32::MIN_POSITIVE / 2.0,
                7.0,
            ],
        };
        let b = odd.to_bytes();
        assert_eq!(VolFile::parse(Path::new("t"), &b).unwrap().to_bytes(), b);
    }

    #[test]
    fn grid_cells_are_the_file_order() {
        let g = sample().to_grid(Path::new("t")).unwrap();
        assert_eq!(g.dims, vec![3, 2, 4]);
        // Cell (x 1, y 0, z 2) covers [1/3, 2/3] × [0, 1/2] × [1/2, 3/4].
        let i = g.cell_index(&[0.5, 0.25, 0.6]);
        assert_eq!(i, 1 + 3 * (2 * 2));
        assert_eq!(g.mass[i], (1 + 3 * 4) as f32 * 0.25);
        assert!(g.ratio.is_empty());
    }

    fn format_error(bytes: &[u8]) -> (usize, String) {
        match VolFile::parse(Path::new("bad.vol"), bytes) {
            Err(VolError::Format {
                offset, message, ..
            }) => (offset, message),
            other => panic!("expected a format error, got {other:?}"),
        }
    }

    #[test]
    fn bad_headers_and_sizes_name_the_offset() {
        let good = sample().to_bytes();
        let patch = |offset: usize, bytes: &[u8]| {
            let mut b = good.clone();
            b[offset..offset + bytes.len()].copy_from_slice(bytes);
            b
        };
        assert_eq!(format_error(&good[..20]).0, 20);
        let (o, m) = format_error(&patch(0, b"VOX"));
        assert!(o == 0 && m.contains("not \"VOL\""), "{m}");
        let (o, m) = format_error(&patch(3, &[2]));
        assert!(o == 3 && m.contains("version 2"), "{m}");
        let (o, m) = format_error(&patch(4, &2i32.to_le_bytes()));
        assert!(
            o == 4 && m.contains("float16") && m.contains("float32"),
            "{m}"
        );
        let (o, m) = format_error(&patch(12, &0i32.to_le_bytes()));
        assert!(o == 12 && m.contains("y resolution is 0"), "{m}");
        let (o, m) = format_error(&patch(16, &(-4i32).to_le_bytes()));
        assert!(o == 16 && m.contains("z resolution is -4"), "{m}");
        let (o, _) = format_error(&patch(20, &0i32.to_le_bytes()));
        assert_eq!(o, 20);
        let (o, m) = format_error(&patch(8, &i32::MAX.to_le_bytes()));
        assert!(o == 8 && m.contains("downsample"), "{m}");
        // Found by the fuzzer (`vol` target, overflow checks on): sizes whose product overflows
        // u64 panicked; wrapped, 2^30 × 2^30 × 16 cells made 0 values and a 48-byte file parsed.
        let mut huge = good[..HEADER_BYTES].to_vec();
        for (at, v) in [(8, 1i32 << 30), (12, 1 << 30), (16, 16)] {
            huge[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        let (o, m) = format_error(&huge);
        assert!(
            o == 8 && m.contains("at least 2^64") && m.contains("downsample"),
            "{m}"
        );
        for v in [i32::MAX; 3] {
            huge[12..16].copy_from_slice(&v.to_le_bytes());
        }
        huge[8..12].copy_from_slice(&i32::MAX.to_le_bytes());
        huge[16..20].copy_from_slice(&i32::MAX.to_le_bytes());
        huge[20..24].copy_from_slice(&i32::MAX.to_le_bytes());
        let (o, m) = format_error(&huge);
        assert!(o == 8 && m.contains("at least 2^64"), "{m}");
        // Truncated data: the offset is where the file ends.
        let (o, m) = format_error(&good[..good.len() - 4]);
        assert!(o == good.len() - 4 && m.contains("truncated"), "{m}");
        // Trailing bytes: the offset is where the values should have ended.
        let mut long = good.clone();
        long.extend_from_slice(&[0; 3]);
        let (o, m) = format_error(&long);
        assert!(o == good.len() && m.contains("after the last value"), "{m}");
        // A header announcing more values than there are.
        let (o, m) = format_error(&patch(8, &4i32.to_le_bytes()));
        assert!(o == good.len() && m.contains("4×2×4"), "{m}");
    }

    #[test]
    fn non_density_values_name_their_cell_and_offset() {
        for bad in [f32::NAN, f32::INFINITY, -0.5] {
            let mut v = sample();
            v.data[13] = bad;
            let e = v.to_grid(Path::new("bad.vol")).unwrap_err();
            let VolError::Format {
                offset, message, ..
            } = &e
            else {
                panic!("{e}")
            };
            assert_eq!(*offset, HEADER_BYTES + 4 * 13);
            // 13 = x 1 + 3 (y 0 + 2 z 2).
            assert!(message.contains("(x 1, y 0, z 2)"), "{message}");
            assert!(e.to_string().contains("bad.vol"), "{e}");
        }
        let mut v = sample();
        v.data.fill(0.0);
        assert!(v
            .to_grid(Path::new("t"))
            .unwrap_err()
            .to_string()
            .contains("every value is 0"));
        let mut v = sample();
        v.channels = 2;
        v.dims = [3, 2, 2];
        assert!(v
            .to_grid(Path::new("t"))
            .unwrap_err()
            .to_string()
            .contains("exactly 1"));
    }

    #[test]
    fn padding_keeps_proportions_and_mass() {
        // 3 × 2 × 4 cells of side 0.5: padded to 4³, x starts at cell 0, y at 1, z at 0.
        let mut v = sample();
        v.bbox = [0.0, 0.0, 0.0, 1.5, 1.0, 2.0];
        let g = v.to_placed_grid(Path::new("t"), VolFit::Pad).unwrap();
        assert_eq!(g.dims, vec![4; 3]);
        assert_eq!(
            g.total_mass(),
            v.to_grid(Path::new("t")).unwrap().total_mass()
        );
        // File cell (x 2, y 1, z 3) → grid cell (2, 2, 3).
        assert_eq!(g.mass[2 + 4 * (2 + 4 * 3)], v.data[2 + 3 * (1 + 2 * 3)]);
        assert_eq!(g.mass[3 + 4 * (2 + 4 * 3)], 0.0);
        // y cell 0 is padding.
        assert_eq!(g.mass[2 + 4 * 4 * 3], 0.0);
        // Non-cubic cells are refused, naming the bounding box's offset.
        v.bbox = [0.0, 0.0, 0.0, 3.0, 1.0, 2.0];
        let e = v.to_placed_grid(Path::new("t"), VolFit::Pad).unwrap_err();
        assert!(
            e.to_string().contains("byte offset 24") && e.to_string().contains("cubic"),
            "{e}"
        );
        // Stretch ignores the box.
        assert_eq!(
            v.to_placed_grid(Path::new("t"), VolFit::Stretch)
                .unwrap()
                .dims,
            vec![3, 2, 4]
        );
    }

    #[test]
    fn the_shared_smoke_grid_round_trips_byte_for_byte() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../shared/data/volumes/smoke_44x45x53.vol");
        let bytes = std::fs::read(&path).unwrap();
        let v = VolFile::parse(&path, &bytes).unwrap();
        assert_eq!((v.dims, v.channels), ([44, 45, 53], 1));
        assert_eq!(v.to_bytes(), bytes);
        let g = v.to_grid(&path).unwrap();
        assert!((g.mean_mass() - 0.108).abs() < 1e-3, "{}", g.mean_mass());
        // Its cells are cubic within 0.4%: it can be padded to 53³.
        let padded = v.to_placed_grid(&path, VolFit::Pad).unwrap();
        assert_eq!(padded.dims, vec![53; 3]);
    }
}
