//! Output sheet sizes that engines accept: a fixed sheet size the packer fills (`sheet_size`),
//! sides rounded to a power of two (`pow2`) or to a multiple of N (`align`), and the texel scale
//! of every chart (`texel_scale`).
//!
//! The rule: the packer's limit is the fixed size when one is given; else `max_sheet_size`
//! rounded *down* to the allowed sides (so no sheet passes the limit the user set); else the
//! largest input sheet rounded *up* (so the default loses no resolution). After trimming, a
//! sheet of a fixed-size run gets exactly that size when its charts fit in it; every other sheet
//! gets its trimmed sides rounded up to the allowed sides. Without any of these options the
//! sheets are trimmed as before, byte for byte.

use super::PackOptions;

/// The largest texel scale: beyond it a chart's footprint would outgrow any sheet.
pub const MAX_TEXEL_SCALE: f64 = 16.0;
/// The smallest texel scale: below it whole charts shrink to a few texels.
pub const MIN_TEXEL_SCALE: f64 = 0.01;
/// The largest `align`.
pub const MAX_ALIGN: u32 = 4096;

impl PackOptions {
    /// Whether the charts keep the input's texel grid, so that texels can be copied verbatim:
    /// only at a texel scale of exactly 1.
    pub fn keeps_input_grid(&self) -> bool {
        self.texel_scale == 1.0
    }

    /// Whether `side` is an allowed sheet side (a power of two with `pow2`, a multiple of
    /// `align`).
    pub fn side_allowed(&self, side: u32) -> bool {
        (!self.pow2 || side.is_power_of_two()) && side.is_multiple_of(self.align.max(1))
    }

    /// The smallest allowed side of at least `side` (saturating at `u32::MAX`).
    pub fn side_up(&self, side: u32) -> u32 {
        let mut s = u64::from(side.max(1));
        if self.pow2 {
            s = s.next_power_of_two();
        }
        let a = u64::from(self.align.max(1));
        s = s.div_ceil(a) * a;
        u32::try_from(s).unwrap_or(u32::MAX)
    }

    /// The largest allowed side of at most `side` (0 when none is).
    pub fn side_down(&self, side: u32) -> u32 {
        let mut s = side;
        if self.pow2 && s > 0 {
            s = 1 << (31 - s.leading_zeros());
        }
        let a = self.align.max(1);
        s / a * a
    }
}

/// The packer's sheet size limit (see the module documentation): the fixed `sheet_size`, else
/// `max_sheet_size` rounded down to the allowed sides, else the largest input sheet (by area,
/// then width) rounded up, else 1 × 1.
pub fn max_sheet_size(opts: &PackOptions, input_sheet_sizes: &[(u32, u32)]) -> (u32, u32) {
    if let Some(fixed) = opts.sheet_size {
        return fixed;
    }
    match opts.max_sheet_size {
        Some((w, h)) => (opts.side_down(w), opts.side_down(h)),
        None => {
            let (w, h) = input_sheet_sizes
                .iter()
                .copied()
                .max_by_key(|&(w, h)| (u64::from(w) * u64::from(h), w))
                .unwrap_or((1, 1));
            (opts.side_up(w), opts.side_up(h))
        }
    }
}

/// The size of an output sheet whose charts were trimmed to `trimmed`, and whether a fixed size
/// was asked for that the sheet could not keep (a chart larger than the fixed sheet). Such a
/// sheet grows only along the axis the chart outgrows, so no side falls below the fixed one.
pub fn output_sheet_size(trimmed: (u32, u32), opts: &PackOptions) -> ((u32, u32), bool) {
    match opts.sheet_size {
        Some(fixed) if trimmed.0 <= fixed.0 && trimmed.1 <= fixed.1 => (fixed, false),
        Some(fixed) => {
            let side = |t: u32, f: u32| if t <= f { f } else { opts.side_up(t) };
            ((side(trimmed.0, fixed.0), side(trimmed.1, fixed.1)), true)
        }
        None => ((opts.side_up(trimmed.0), opts.side_up(trimmed.1)), false),
    }
}

/// Refuses sheet-shape options no run can honour, with a message naming the option.
pub fn check_sheet_shape(opts: &PackOptions) -> Result<(), String> {
    let s = opts.texel_scale;
    if !(s.is_finite() && (MIN_TEXEL_SCALE..=MAX_TEXEL_SCALE).contains(&s)) {
        // Huge values in scientific notation, so a typo does not print three hundred digits.
        let shown = if s.abs() < 1e6 { s.to_string() } else { format!("{s:e}") };
        return Err(format!(
            "--texel-scale {shown}: expected a number from {MIN_TEXEL_SCALE} to {MAX_TEXEL_SCALE}"
        ));
    }
    if !(1..=MAX_ALIGN).contains(&opts.align) {
        return Err(format!("--align {}: expected 1 to {MAX_ALIGN}", opts.align));
    }
    if opts.pow2 && !opts.align.is_power_of_two() {
        return Err(format!(
            "--align {} with --pow2: no power of two is a multiple of it; use a power of two",
            opts.align
        ));
    }
    if let Some((w, h)) = opts.sheet_size {
        if opts.max_sheet_size.is_some() {
            return Err("--sheet-size and --max-sheet-size exclude each other".into());
        }
        if w == 0 || h == 0 {
            return Err(format!("--sheet-size {w}x{h}: each side must be at least 1"));
        }
        if !(opts.side_allowed(w) && opts.side_allowed(h)) {
            return Err(format!(
                "--sheet-size {w}x{h} does not satisfy {}: try {}x{}",
                shape_words(opts),
                opts.side_up(w),
                opts.side_up(h)
            ));
        }
    }
    if let Some((w, h)) = opts.max_sheet_size
        && (opts.side_down(w) == 0 || opts.side_down(h) == 0)
    {
        return Err(format!(
            "--max-sheet-size {w}x{h} leaves no sheet side that satisfies {}",
            shape_words(opts)
        ));
    }
    Ok(())
}

/// `--pow2`, `--align N` or both, as the user wrote them.
fn shape_words(opts: &PackOptions) -> String {
    match (opts.pow2, opts.align) {
        (true, 1) => "--pow2".into(),
        (true, a) => format!("--pow2 --align {a}"),
        (false, a) => format!("--align {a}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(pow2: bool, align: u32) -> PackOptions {
        PackOptions { pow2, align, ..PackOptions::default() }
    }

    #[test]
    fn sides_round_up_and_down_to_powers_of_two_and_multiples() {
        let p = opts(true, 1);
        assert_eq!(
            [p.side_up(1), p.side_up(3), p.side_up(1024), p.side_up(1025)],
            [1, 4, 1024, 2048]
        );
        assert_eq!(
            [p.side_down(0), p.side_down(3), p.side_down(1024), p.side_down(2047)],
            [0, 2, 1024, 1024]
        );
        let a = opts(false, 4);
        assert_eq!([a.side_up(1), a.side_up(1208), a.side_up(1209)], [4, 1208, 1212]);
        assert_eq!([a.side_down(3), a.side_down(1299)], [0, 1296]);
        let both = opts(true, 16);
        assert_eq!([both.side_up(5), both.side_up(17), both.side_down(15)], [16, 32, 0]);
        assert_eq!(opts(true, 1).side_up(u32::MAX), u32::MAX);
        let none = PackOptions::default();
        assert_eq!([none.side_up(1297), none.side_down(1297)], [1297, 1297]);
    }

    #[test]
    fn the_limit_is_the_fixed_size_or_rounded_down_or_the_input_rounded_up() {
        let inputs = [(3000, 2000), (1000, 1000)];
        assert_eq!(max_sheet_size(&PackOptions::default(), &inputs), (3000, 2000));
        assert_eq!(max_sheet_size(&opts(true, 1), &inputs), (4096, 2048));
        let max = PackOptions { max_sheet_size: Some((1000, 600)), ..opts(true, 1) };
        assert_eq!(max_sheet_size(&max, &inputs), (512, 512));
        let fixed = PackOptions { sheet_size: Some((256, 128)), ..opts(true, 1) };
        assert_eq!(max_sheet_size(&fixed, &inputs), (256, 128));
    }

    #[test]
    fn fixed_sheets_keep_their_size_unless_a_chart_outgrows_them() {
        let fixed = PackOptions { sheet_size: Some((512, 512)), ..opts(true, 1) };
        assert_eq!(output_sheet_size((300, 512), &fixed), ((512, 512), false));
        // The sheet grows only along the axis the chart outgrows: never below the fixed size.
        assert_eq!(output_sheet_size((700, 20), &fixed), ((1024, 512), true));
        assert_eq!(output_sheet_size((300, 70), &opts(false, 8)), ((304, 72), false));
        assert_eq!(output_sheet_size((301, 71), &PackOptions::default()), ((301, 71), false));
    }

    #[test]
    fn impossible_shapes_are_refused_with_the_option_named() {
        let ok = |o: PackOptions| check_sheet_shape(&o);
        assert!(ok(PackOptions::default()).is_ok());
        let e = ok(PackOptions { sheet_size: Some((1000, 1024)), ..opts(true, 1) }).unwrap_err();
        assert!(e.contains("--sheet-size 1000x1024") && e.contains("1024x1024"), "{e}");
        let e = ok(opts(true, 12)).unwrap_err();
        assert!(e.contains("--align 12"), "{e}");
        let e = ok(PackOptions { max_sheet_size: Some((10, 10)), ..opts(false, 16) }).unwrap_err();
        assert!(e.contains("--max-sheet-size"), "{e}");
        let both = PackOptions {
            sheet_size: Some((8, 8)),
            max_sheet_size: Some((8, 8)),
            ..PackOptions::default()
        };
        assert!(ok(both).unwrap_err().contains("exclude"));
        for s in [0.0, -1.0, f64::NAN, 100.0] {
            let e = ok(PackOptions { texel_scale: s, ..PackOptions::default() }).unwrap_err();
            assert!(e.contains("--texel-scale"), "{e}");
        }
        assert!(ok(opts(false, 0)).unwrap_err().contains("--align 0"));
    }
}
