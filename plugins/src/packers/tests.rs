//! Seeded randomized and targeted tests of the built-in packers: every answer passes the exact
//! checker of `scanatlas_core::plugin::check_packing` (no overlap, inside the sheet, allowed
//! turns), answers are deterministic, sheets overflow into new ones and oversized items get their
//! own sheet.

use scanatlas_core::plugin::{
    ALL_ROTATIONS, Footprint, PackItem, PackOutput, Packer, Params, Registry, check_packing,
};

use super::fixtures::{density, filled, mixed_charts, random_items};
use super::{HorizonPacker, SkylinePacker};

fn packers() -> Vec<(&'static str, Box<dyn Packer>)> {
    vec![
        ("horizon", Box::new(HorizonPacker::default())),
        ("horizon-wide", Box::new(HorizonPacker { square: false, ..HorizonPacker::default() })),
        (
            "horizon-paper-fit",
            Box::new(HorizonPacker { area_fits: false, ..HorizonPacker::default() }),
        ),
        ("skyline", Box::new(SkylinePacker)),
        ("rows", Box::new(super::RowsPacker)),
    ]
}

fn run(p: &dyn Packer, items: &[PackItem], sheet: (u32, u32)) -> PackOutput {
    let out = p.pack(items, sheet).unwrap();
    check_packing(items, sheet, &out).unwrap();
    out
}

#[test]
fn random_instances_never_overlap_and_are_deterministic() {
    for seed in 0..40u64 {
        let n = 1 + (seed as usize * 7) % 60;
        let items = random_items(seed, n, 1 + (seed as u32 % 5) * 10);
        let sheet = (40 + (seed as u32 % 3) * 30, 50 + (seed as u32 % 4) * 20);
        for (name, p) in packers() {
            let a = run(p.as_ref(), &items, sheet);
            let b = run(p.as_ref(), &items, sheet);
            assert_eq!(a, b, "{name} seed {seed}");
        }
    }
}

#[test]
fn overflow_opens_sheets_and_oversized_items_get_their_own() {
    // 30 squares of 10×10 on 32×32 sheets: at most 9 per sheet.
    let mut items: Vec<PackItem> = (0..30)
        .map(|_| PackItem { footprint: Footprint::filled(10, 10).unwrap(), rotations: 1 })
        .collect();
    // 50×20 fits no 32×32 sheet in any turn, and 40×20 may not turn at all: both are oversized.
    items
        .push(PackItem { footprint: Footprint::filled(50, 20).unwrap(), rotations: ALL_ROTATIONS });
    items.push(PackItem { footprint: Footprint::filled(40, 20).unwrap(), rotations: 1 });
    for (name, p) in packers() {
        let out = run(p.as_ref(), &items, (32, 32));
        assert_eq!(out.oversized, vec![30, 31], "{name}");
        let s30 = out.placements[30].sheet as usize;
        assert!(
            out.sheets[s30] == (50, 20) || out.sheets[s30] == (20, 50),
            "{name}: {:?}",
            out.sheets[s30]
        );
        assert_eq!(out.sheets[out.placements[31].sheet as usize], (40, 20));
        let normal = out.sheets.len() - 2;
        assert!((4..=5).contains(&normal), "{name}: {normal} sheets");
    }
}

#[test]
fn horizon_fills_the_gap_under_an_overhang() {
    // A wide "table": a 30×4 top on two 2×10 legs, open below; then a 20×7 block. The block fits
    // between the legs (gap 26 wide, 10 high) and must go there instead of on top.
    let mut table = Footprint::new(30, 14).unwrap();
    for y in 0..14 {
        table.set_span(y, 0, 2);
        table.set_span(y, 28, 30);
    }
    for y in 10..14 {
        table.set_span(y, 0, 30);
    }
    let items = vec![
        PackItem { footprint: table, rotations: 1 },
        PackItem { footprint: Footprint::filled(20, 7).unwrap(), rotations: 1 },
    ];
    // The table is placed first (largest); the block sits under it.
    let out = run(&HorizonPacker { square: false, ..HorizonPacker::default() }, &items, (30, 40));
    assert_eq!(out.sheets.len(), 1);
    assert!(out.placements[1].y < 10, "{:?}", out.placements);
}

#[test]
fn horizon_is_at_least_as_dense_as_skyline_on_irregular_shapes() {
    let items = random_items(99, 300, 24);
    let a = run(&HorizonPacker::default(), &items, (256, 256));
    let b = run(&SkylinePacker, &items, (256, 256));
    let all: Vec<u32> = (0..items.len() as u32).collect();
    let area = |o: &PackOutput| super::used_area(&items, &o.placements, &all, o.sheets.len());
    assert!(area(&a) <= area(&b), "horizon {} vs skyline {}", area(&a), area(&b));
}

#[test]
fn registered_by_name_with_parameters() {
    let mut r = Registry::default();
    crate::register_builtin(&mut r);
    let mut p = Params::new();
    p.insert("seed".into(), scanatlas_core::plugin::ParamValue::Int(3));
    assert!(r.packer("horizon", &p).is_ok());
    assert!(r.packer("skyline", &Params::new()).is_ok());
    assert!(r.packer("skyline", &p).is_err(), "skyline has no seed");
    assert!(r.packer("maxrects", &Params::new()).is_err());
}

/// A tenth of the scale of a real defragmented scan (the `pack` benchmark runs the full 10k):
/// 1,000 charts of mixed sizes, as U-shaped blobs and as solid boxes, on 2048² sheets. Every
/// packer gives a valid packing, and horizon is at least as dense as skyline on the blobs.
#[test]
fn a_thousand_mixed_charts_on_large_sheets() {
    let blobs = mixed_charts(1_000);
    let boxes = filled(&blobs);
    for items in [&blobs, &boxes] {
        for (name, p) in packers() {
            let out = run(p.as_ref(), items, (2048, 2048));
            let d = density(items, &out);
            assert!(d > 0.05 && d <= 1.0, "{name}: density {d}");
        }
    }
    let h = density(&blobs, &run(&HorizonPacker::default(), &blobs, (2048, 2048)));
    let s = density(&blobs, &run(&SkylinePacker, &blobs, (2048, 2048)));
    assert!(h >= s, "horizon {h} vs skyline {s}");
}

/// The square start never loses to the full-width start: both passes run and the smaller
/// packing is kept, so on every instance the default packs into at most the sheets and the
/// trimmed area of `square: false` (an atlas of about one sheet packed square first used to
/// strand charts in the strips of its growth steps).
#[test]
fn the_default_horizon_is_never_worse_than_the_full_width_start() {
    let wide = HorizonPacker { square: false, ..HorizonPacker::default() };
    for seed in 0..12u64 {
        let items = random_items(seed, 150 + 40 * seed as usize, 48);
        let all: Vec<u32> = (0..items.len() as u32).collect();
        let score = |o: &PackOutput| {
            (o.sheets.len(), super::used_area(&items, &o.placements, &all, o.sheets.len()))
        };
        let a = run(&HorizonPacker::default(), &items, (512, 512));
        let b = run(&wide, &items, (512, 512));
        assert!(
            score(&a) <= score(&b),
            "seed {seed}: default {:?} vs wide {:?}",
            score(&a),
            score(&b)
        );
    }
}

/// The passes that weigh stranded area run beside the paper's lowest-horizon passes and the
/// densest is kept, so the default never packs worse than the paper's rule alone (without
/// shuffles, which only ever improve on the passes); on these irregular instances it packs
/// strictly denser in total.
#[test]
fn the_area_fits_never_lose_to_the_lowest_horizon_rule_alone() {
    let paper = HorizonPacker { area_fits: false, shuffle_below: 0, ..HorizonPacker::default() };
    let both = HorizonPacker { shuffle_below: 0, ..HorizonPacker::default() };
    let (mut sum_paper, mut sum_both) = (0u64, 0u64);
    for seed in 0..12u64 {
        let items = random_items(100 + seed, 200 + 30 * seed as usize, 40);
        let all: Vec<u32> = (0..items.len() as u32).collect();
        let score = |o: &PackOutput| {
            (o.sheets.len(), super::used_area(&items, &o.placements, &all, o.sheets.len()))
        };
        let a = score(&run(&both, &items, (1024, 1024)));
        let b = score(&run(&paper, &items, (1024, 1024)));
        assert!(a <= b, "seed {seed}: with area fits {a:?} vs lowest horizon only {b:?}");
        sum_both += a.1;
        sum_paper += b.1;
    }
    assert!(sum_both < sum_paper, "area fits {sum_both} vs lowest horizon only {sum_paper}");
}

/// An S 60 cells wide and 50 tall: three bars 10 rows thick joined by posts on alternate sides,
/// so a pocket 50 cells wide and 10 tall opens to the left (rows 10..20) and one to the right
/// (rows 30..40).
fn s_shape() -> Footprint {
    let mut f = Footprint::new(60, 50).unwrap();
    for y in (0..10).chain(20..30).chain(40..50) {
        f.set_span(y, 0, 60);
    }
    for y in 10..20 {
        f.set_span(y, 50, 60);
    }
    for y in 30..40 {
        f.set_span(y, 0, 10);
    }
    f
}

#[test]
fn bars_nest_in_the_pockets_of_an_s_instead_of_opening_a_second_sheet() {
    // The S fills the sheet's box; each bar fits one pocket, and the three take 2720 of the
    // sheet's 3000 cells. The horizons see every column of the S as solid, so without nesting
    // the bars went to a second sheet.
    let bar =
        || PackItem { footprint: Footprint::filled(45, 8).unwrap(), rotations: ALL_ROTATIONS };
    let items = vec![PackItem { footprint: s_shape(), rotations: ALL_ROTATIONS }, bar(), bar()];
    let sheet = (60, 50);
    let plain = HorizonPacker { nest: false, ..HorizonPacker::default() };
    assert_eq!(run(&plain, &items, sheet).sheets.len(), 2);
    let out = run(&HorizonPacker::default(), &items, sheet);
    assert_eq!(out.sheets.len(), 1, "{:?}", out.placements);
    assert_eq!(out, run(&HorizonPacker::default(), &items, sheet));
}
