//! The ground-truth colour of synthetic surfaces, and the sRGB transfer function.
//!
//! [`true_color`] is a pure function of the 3D point: a sum of plane waves (sines) at six scales,
//! so its spectrum is known exactly. Synthetic models are generated about two units across (a
//! blob has radius ≈ 1), and the waves have these wavelengths in model units:
//!
//! | octave | wavelength | role                                  |
//! |--------|------------|---------------------------------------|
//! | 0      | 0.9        | palette choice (warped)               |
//! | 1      | 0.3        | palette choice (warped)               |
//! | 2      | 0.1        | brightness (warped)                   |
//! | 3      | 0.033      | brightness                            |
//! | 4      | 0.011      | brightness                            |
//! | 5      | 0.0037     | brightness, finest detail             |
//!
//! A low-frequency domain warp (wavelength 2.5, amplitude 0.12) bends octaves 0 to 2 so the
//! pattern looks organic; it shifts their local wavelength by at most about 30 %. Octaves 3 to 5
//! are unwarped pure sines, so the finest wavelength anywhere is 0.0037 units.
//!
//! With the default 16 sheets of 4096² for a million-face blob (about 3000 texels per unit,
//! texel ≈ 0.0003 units) the finest octave spans about 12 texels: well band-limited, yet
//! bilinear resampling and sub-texel shifts change texels measurably. On tiny test atlases the
//! finest octaves alias, but they carry only a few percent of the signal.

use std::sync::OnceLock;

use crate::rng::SplitMix64;

/// One plane wave `sin(k · p + phase)`.
#[derive(Clone, Copy, Debug)]
struct Wave {
    k: [f64; 3],
    phase: f64,
}

impl Wave {
    #[inline]
    fn eval(&self, p: [f64; 3]) -> f64 {
        sin(self.k[0] * p[0] + self.k[1] * p[1] + self.k[2] * p[2] + self.phase)
    }
}

/// Sine by explicit range reduction to `[−π, π]` and a degree-17 Taylor polynomial: absolute
/// error below 1e-7 (far under one 8-bit level), branch-free and without library calls, so it is
/// several times faster than `f64::sin` on the large arguments of the fine octaves, and plain
/// arithmetic, so the true colour is bit-identical on every platform (the C library's `sin` and
/// `round` need not be).
#[inline]
fn sin(x: f64) -> f64 {
    use std::f64::consts::TAU;
    // Adding and subtracting 1.5·2^52 rounds to the nearest integer (|t| < 2^51) with plain
    // arithmetic; `f64::round` is a library call on baseline x86-64.
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let t = x * (1.0 / TAU);
    let y = (t - ((t + MAGIC) - MAGIC)) * TAU;
    let y2 = y * y;
    // Horner form of Σ (−1)^k y^(2k+1) / (2k+1)!, k = 0..=8.
    const C: [f64; 9] = [
        1.0,
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
        -1.0 / 1_307_674_368_000.0,
        1.0 / 355_687_428_096_000.0,
    ];
    let mut acc = C[8];
    for &c in C[..8].iter().rev() {
        acc = acc * y2 + c;
    }
    y * acc
}

/// Wavelengths of the six octaves, in model units (see the module table).
pub const OCTAVE_WAVELENGTHS: [f64; 6] = [0.9, 0.3, 0.1, 0.033, 0.011, 0.0037];
const WAVES_PER_OCTAVE: usize = 2;
const WARP_WAVELENGTH: f64 = 2.5;
const WARP_AMPLITUDE: f64 = 0.12;

struct Waves {
    warp: [Wave; 3],
    octaves: [[Wave; WAVES_PER_OCTAVE]; 6],
}

/// The fixed wave table: directions and phases drawn once from a constant seed, so
/// `true_color` is the same function in every run and every build.
fn waves() -> &'static Waves {
    static TABLE: OnceLock<Waves> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut rng = SplitMix64::new(0x5CA4_A71A_5C01_0123);
        let mut wave = |wavelength: f64| {
            // A uniformly random direction: normalize a Gaussian-ish vector (sum of uniforms is
            // plenty for picking a handful of directions).
            let mut d = [0.0f64; 3];
            loop {
                for c in &mut d {
                    *c = rng.range(-1.0, 1.0);
                }
                let n2: f64 = d.iter().map(|c| c * c).sum();
                if (0.05..=1.0).contains(&n2) {
                    let n = n2.sqrt();
                    d = d.map(|c| c / n);
                    break;
                }
            }
            let k = std::f64::consts::TAU / wavelength;
            Wave { k: d.map(|c| c * k), phase: rng.range(0.0, std::f64::consts::TAU) }
        };
        let warp = [wave(WARP_WAVELENGTH), wave(WARP_WAVELENGTH), wave(WARP_WAVELENGTH)];
        let octaves = OCTAVE_WAVELENGTHS.map(|l| [wave(l), wave(l)]);
        Waves { warp, octaves }
    })
}

/// Linear-RGB palette the low octaves blend through (earth, terracotta, moss, slate).
const PALETTE: [[f64; 3]; 4] =
    [[0.62, 0.46, 0.27], [0.52, 0.19, 0.08], [0.17, 0.27, 0.09], [0.23, 0.25, 0.31]];

#[inline]
fn palette(t: f64) -> [f64; 3] {
    let x = t.clamp(0.0, 1.0) * (PALETTE.len() - 1) as f64;
    // x ≥ 0, so truncation is the floor (and avoids a library call).
    let i = (x as usize).min(PALETTE.len() - 2);
    let f = x - i as f64;
    let (a, b) = (PALETTE[i], PALETTE[i + 1]);
    [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]
}

/// The procedural ground-truth colour of surface point `p`, linear RGB in `[0, 1]`.
/// Deterministic and pure: the same point always has the same colour.
pub fn true_color(p: [f64; 3]) -> [f64; 3] {
    color_with_detail(p, 1.0)
}

/// Wavelength (model units) of the field that decides where [`patchy_color`] is smooth.
const PATCH_WAVELENGTH: f64 = 1.25;
/// Width of the ramp between detailed and smooth patches, in units of that field.
const PATCH_RAMP: f64 = 0.03;

/// The weight of the detail octaves (1 to 5) at `p` when about a fraction `smooth` of the
/// surface is to be smooth: 0 in the smooth patches, 1 elsewhere, a short ramp between. The
/// patches follow a low-frequency field (two plane waves of wavelength [`PATCH_WAVELENGTH`]);
/// the fraction is that of a single sine's level set, so only approximate.
pub fn detail_weight(p: [f64; 3], smooth: f64) -> f64 {
    if smooth <= 0.0 {
        return 1.0;
    }
    let w = waves();
    let s = WARP_WAVELENGTH / PATCH_WAVELENGTH;
    let q = [p[0] * s, p[1] * s, p[2] * s];
    let field = 0.5 * (w.warp[0].eval(q) + w.warp[1].eval(q));
    let t = 0.5 * sin(std::f64::consts::PI * (smooth.min(1.0) - 0.5));
    let x = ((field - t) / (2.0 * PATCH_RAMP) + 0.5).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// [`true_color`] with smooth patches: every octave but the first (wavelengths 0.3 and below)
/// faded out over about a fraction `smooth` of the surface ([`detail_weight`]), leaving only the
/// palette octave of wavelength 0.9 there. A capture of such a surface has regions a coarse
/// pyramid level textures as well as the photo, as real scans of plaster, skin or sky have.
/// `smooth = 0` is exactly [`true_color`].
pub fn patchy_color(p: [f64; 3], smooth: f64) -> [f64; 3] {
    color_with_detail(p, detail_weight(p, smooth))
}

/// The colour with the detail octaves weighted by `m` (1 = [`true_color`], bit for bit, since
/// multiplying by one is exact).
fn color_with_detail(p: [f64; 3], m: f64) -> [f64; 3] {
    let w = waves();
    let q = [
        p[0] + WARP_AMPLITUDE * w.warp[0].eval(p),
        p[1] + WARP_AMPLITUDE * w.warp[1].eval(p),
        p[2] + WARP_AMPLITUDE * w.warp[2].eval(p),
    ];
    let oct = |o: usize, x: [f64; 3]| 0.5 * (w.octaves[o][0].eval(x) + w.octaves[o][1].eval(x));
    let (s0, s1, s2) = (oct(0, q), oct(1, q) * m, oct(2, q) * m);
    let (s3, s4, s5) = (oct(3, p) * m, oct(4, p) * m, oct(5, p) * m);
    let base = palette(0.5 + 0.38 * s0 + 0.17 * s1);
    let detail = (0.5 * s2 + 0.35 * s3 + 0.25 * s4 + 0.18 * s5) / 1.28;
    let lum = 0.74 + 0.26 * detail;
    // A slight warm/cool shift at the 0.033 scale keeps fine detail from being pure luminance.
    let tint = 0.035 * s3;
    [
        (base[0] * lum + tint).clamp(0.0, 1.0),
        (base[1] * lum).clamp(0.0, 1.0),
        (base[2] * lum - tint).clamp(0.0, 1.0),
    ]
}

/// Entries of the linear → sRGB lookup table; fine enough that the table is off by at most one
/// 8-bit level, and only in the steep dark end.
const LUT_SIZE: usize = 1 << 14;

fn srgb_encode_exact(l: f64) -> f64 {
    if l <= 0.003_130_8 { 12.92 * l } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

fn srgb_lut() -> &'static [u8; LUT_SIZE] {
    static LUT: OnceLock<[u8; LUT_SIZE]> = OnceLock::new();
    LUT.get_or_init(|| {
        let mut t = [0u8; LUT_SIZE];
        for (i, v) in t.iter_mut().enumerate() {
            let l = i as f64 / (LUT_SIZE - 1) as f64;
            *v = (srgb_encode_exact(l) * 255.0).round().clamp(0.0, 255.0) as u8;
        }
        t
    })
}

/// A linear intensity in `[0, 1]` (clamped) as an 8-bit sRGB value.
#[inline]
pub fn linear_to_srgb8(l: f64) -> u8 {
    let i = (l.clamp(0.0, 1.0) * (LUT_SIZE - 1) as f64 + 0.5) as usize;
    srgb_lut()[i]
}

/// An 8-bit sRGB value as a linear intensity in `[0, 1]`.
#[inline]
pub fn srgb8_to_linear(v: u8) -> f64 {
    let s = v as f64 / 255.0;
    if s <= 0.040_45 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn true_color_is_pure_bounded_and_varied() {
        let mut lo = [1.0f64; 3];
        let mut hi = [0.0f64; 3];
        for i in 0..5000 {
            let p = [i as f64 * 0.0137 - 30.0, (i as f64 * 0.31).sin(), (i as f64 * 0.07).cos()];
            let c = true_color(p);
            assert_eq!(c, true_color(p), "pure");
            for k in 0..3 {
                assert!((0.0..=1.0).contains(&c[k]));
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
        for k in 0..3 {
            assert!(hi[k] - lo[k] > 0.2, "channel {k} varies: {lo:?} .. {hi:?}");
        }
    }

    #[test]
    fn true_color_has_detail_at_the_finest_scale_and_is_smooth_below_it() {
        // Across one finest wavelength the colour changes visibly; across 1/100 of it, barely.
        let l = OCTAVE_WAVELENGTHS[5];
        let (mut big, mut small) = (0.0f64, 0.0f64);
        for i in 0..200 {
            let p = [0.1 + i as f64 * 0.01, 0.2, 0.3];
            let d = |q: [f64; 3]| {
                let (a, b) = (true_color(p), true_color(q));
                (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max)
            };
            big = big.max(d([p[0] + l / 2.0, p[1], p[2]]));
            small = small.max(d([p[0] + l / 100.0, p[1], p[2]]));
        }
        assert!(big > 0.02, "detail at the finest scale: {big}");
        assert!(small < 0.01, "smooth below it: {small}");
    }

    #[test]
    fn fast_sine_matches_the_library() {
        for i in -200_000..200_000 {
            let x = i as f64 * 0.0173;
            assert!((sin(x) - x.sin()).abs() < 1e-7, "sin({x})");
        }
    }

    #[test]
    fn srgb_round_trips_every_level() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb8_to_linear(v)), v);
        }
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(2.0), 255);
    }
}
