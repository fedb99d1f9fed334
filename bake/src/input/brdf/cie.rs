//! Spectra (400–700 nm, 10 nm steps) to linear sRGB.
//!
//! Tables: CIE 1931 2° standard observer colour-matching functions and the CIE standard
//! illuminant D65, both from CIE 15:2004 (Colorimetry, 3rd ed.), Table 1 and Table T.1, sampled at
//! 400, 410, …, 700 nm. A reflectance-like spectrum `s(λ)` (a BRDF) is integrated against D65:
//! `X = Σ s x̄ D65 / Σ ȳ D65` (likewise Y, Z), so a flat spectrum of 1 gives the D65 white point
//! `(0.9505, 1, 1.089)`, which the XYZ → linear sRGB matrix (IEC 61966-2-1) maps to about
//! `(1, 1, 1)`. Out-of-gamut colours (negative components) are clipped to 0.

/// Wavelengths in nm.
pub const WAVELENGTHS: [f64; 31] = [
    400.0, 410.0, 420.0, 430.0, 440.0, 450.0, 460.0, 470.0, 480.0, 490.0, 500.0, 510.0, 520.0,
    530.0, 540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 600.0, 610.0, 620.0, 630.0, 640.0, 650.0,
    660.0, 670.0, 680.0, 690.0, 700.0,
];

/// CIE 1931 2° x̄, ȳ, z̄ at [`WAVELENGTHS`].
#[rustfmt::skip]
pub const CMF: [[f64; 3]; 31] = [
    [0.014310, 0.000396, 0.067850], [0.043510, 0.001210, 0.207400], [0.134380, 0.004000, 0.645600],
    [0.283900, 0.011600, 1.385600], [0.348280, 0.023000, 1.747060], [0.336200, 0.038000, 1.772110],
    [0.290800, 0.060000, 1.669200], [0.195360, 0.090980, 1.287640], [0.095640, 0.139020, 0.812950],
    [0.032010, 0.208020, 0.465180], [0.004900, 0.323000, 0.272000], [0.009300, 0.503000, 0.158200],
    [0.063270, 0.710000, 0.078250], [0.165500, 0.862000, 0.042160], [0.290400, 0.954000, 0.020300],
    [0.433450, 0.994950, 0.008750], [0.594500, 0.995000, 0.003900], [0.762100, 0.952000, 0.002100],
    [0.916300, 0.870000, 0.001650], [1.026300, 0.757000, 0.001100], [1.062200, 0.631000, 0.000800],
    [1.002600, 0.503000, 0.000340], [0.854450, 0.381000, 0.000190], [0.642400, 0.265000, 0.000050],
    [0.447900, 0.175000, 0.000020], [0.283500, 0.107000, 0.000000], [0.164900, 0.061000, 0.000000],
    [0.087400, 0.032000, 0.000000], [0.046770, 0.017000, 0.000000], [0.022700, 0.008210, 0.000000],
    [0.011359, 0.004102, 0.000000],
];

/// CIE standard illuminant D65 relative spectral power at [`WAVELENGTHS`].
#[rustfmt::skip]
pub const D65: [f64; 31] = [
    82.7549, 91.4860, 93.4318, 86.6823, 104.865, 117.008, 117.812, 114.861, 115.923, 108.811,
    109.354, 107.802, 104.790, 107.689, 104.405, 104.046, 100.000, 96.3342, 95.7880, 88.6856,
    90.0062, 89.5991, 87.6987, 83.2886, 83.6992, 80.0268, 80.2146, 82.2778, 78.2842, 69.7213,
    71.6091,
];

/// XYZ → linear sRGB (D65), IEC 61966-2-1.
pub const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.240_454_2, -1.537_138_5, -0.498_531_4],
    [-0.969_266_0, 1.876_010_8, 0.041_556_0],
    [0.055_643_4, -0.204_025_9, 1.057_225_2],
];

/// CIE XYZ of a spectrum sampled at [`WAVELENGTHS`], under D65, normalized so that `Y(1) = 1`.
pub fn spectrum_to_xyz(s: &[f64; 31]) -> [f64; 3] {
    let norm: f64 = CMF.iter().zip(&D65).map(|(c, d)| c[1] * d).sum();
    let mut xyz = [0.0; 3];
    for ((v, c), d) in s.iter().zip(&CMF).zip(&D65) {
        for k in 0..3 {
            xyz[k] += v * c[k] * d;
        }
    }
    xyz.map(|x| x / norm)
}

/// Linear sRGB of a spectrum (negative components clipped to 0).
pub fn spectrum_to_rgb(s: &[f64; 31]) -> [f64; 3] {
    let xyz = spectrum_to_xyz(s);
    let mut rgb = [0.0; 3];
    for (r, row) in rgb.iter_mut().zip(&XYZ_TO_SRGB) {
        *r = (row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2]).max(0.0);
    }
    rgb
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_spectrum_is_white_and_bands_have_their_hue() {
        let xyz = spectrum_to_xyz(&[1.0; 31]);
        assert!(
            (xyz[0] - 0.9505).abs() < 0.01 && (xyz[2] - 1.089).abs() < 0.01,
            "{xyz:?}"
        );
        let rgb = spectrum_to_rgb(&[0.5; 31]);
        for c in rgb {
            assert!((c - 0.5).abs() < 0.01, "{rgb:?}");
        }
        let band = |lo: f64, hi: f64| {
            let mut s = [0.0; 31];
            for (v, w) in s.iter_mut().zip(WAVELENGTHS) {
                if (lo..=hi).contains(&w) {
                    *v = 1.0;
                }
            }
            spectrum_to_rgb(&s)
        };
        let blue = band(400.0, 490.0);
        assert!(blue[2] > blue[1] && blue[2] > blue[0], "{blue:?}");
        let red = band(600.0, 700.0);
        assert!(red[0] > 5.0 * red[1] && red[0] > 5.0 * red[2], "{red:?}");
    }
}
