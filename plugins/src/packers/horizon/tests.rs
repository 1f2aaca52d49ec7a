//! Tests of the `horizon` packer's position searches and of its score bound.

use super::*;
use scanatlas_core::plugin::Footprint;

/// A sheet of the given upper horizon, no gaps.
fn sheet(horizon: &[u32]) -> Sheet {
    let n = horizon.len() as u32;
    let mut s = Sheet::new(n, n, 100);
    // Placing one-cell-wide columns of the given heights builds the horizon and its sums.
    for (x, &h) in horizon.iter().enumerate() {
        if h > 0 {
            let col = Profile { turn: 0, width: 1, height: h, cols: vec![(0, 0, h)], tallest: h };
            s.place(&col, x as u32, 0);
        }
    }
    s
}

/// A flat bar three columns wide and one high.
fn bar() -> Profile {
    let item = PackItem { footprint: Footprint::filled(3, 1).unwrap(), rotations: 1 };
    profiles(&item).remove(0)
}

#[test]
fn the_area_fit_trades_a_low_top_for_a_snug_bed() {
    // Columns 0..3 are level at 2; columns 3..6 dip to 0, 1, 0. The lowest top (2) is in
    // the dip, stranding two cells; the level bed has top 3 and strands none.
    let s = sheet(&[2, 2, 2, 0, 1, 0]);
    let p = bar();
    assert_eq!(s.best_outer(&p, 100, Fit::LowestTop), Some((2, 3, 1)));
    // Key top·width·num + stranded·den: the dip 2·3 + 2·2 = 10, the bed 3·3 = 9.
    assert_eq!(s.best_outer(&p, 100, Fit::Area { num: 1, den: 2 }), Some((9, 0, 2)));
    // With equal weights the dip costs 2·3 + 2 = 8 against 9: the low top wins again.
    assert_eq!(s.best_outer(&p, 100, Fit::Area { num: 1, den: 1 }), Some((8, 3, 1)));
}

#[test]
fn a_gap_placement_skips_columns_too_low_for_the_chart() {
    // Everything is filled up to row 9 but for a gap 4..9 in columns 4..7; the other
    // columns have none.
    let mut s = Sheet::new(8, 8, 100);
    s.horizon = vec![9; 8];
    s.gap_lo = vec![0, 0, 0, 0, 4, 4, 4, 0];
    s.gap_hi = vec![0, 0, 0, 0, 9, 9, 9, 0];
    // Placing nothing refreshes the summaries and the prefix sums.
    s.place(&Profile { turn: 0, width: 1, height: 0, cols: vec![], tallest: 0 }, 7, 9);
    let p = bar();
    // Only columns 4..7 have a gap tall enough: the bar rests on their floor at 4.
    assert_eq!(s.best_inner(&p), Some((0, 4, 4)));
}

#[test]
fn the_score_bound_stops_only_trials_that_cannot_win_or_tie() {
    let b = ScoreBound::new((2, 500));
    assert!(!b.beaten(2, 500), "a tie goes on: the first of equals may win");
    assert!(b.beaten(2, 501) && b.beaten(3, 0) && !b.beaten(1, 1 << 40));
    b.lower((1, 900));
    assert!(b.beaten(2, 0) && !b.beaten(1, 900) && b.beaten(1, 901));
    // Scores too large to pack into a word never stop a trial.
    assert!(!b.beaten(1, 1 << 50) && !b.beaten(usize::MAX, 0));
    b.lower((1, 1 << 50));
    assert!(!b.beaten(1, 900));
}

#[test]
fn pruned_shuffles_pack_exactly_as_unpruned_ones() {
    let packer = HorizonPacker::default();
    let mut multi_sheet = false;
    for (seed, n, side, sheet) in
        [(1, 12, 40, 64), (2, 30, 30, 96), (3, 60, 24, 128), (4, 90, 20, 160), (5, 45, 50, 200)]
    {
        let items = super::super::fixtures::random_items(seed, n, side);
        let with = packer.pack_bounded(&items, (sheet, sheet), true).unwrap();
        let without = packer.pack_bounded(&items, (sheet, sheet), false).unwrap();
        assert_eq!(with, without, "seed {seed}: {n} items on {sheet}² sheets");
        multi_sheet |= with.sheets.len() > 1;
    }
    assert!(multi_sheet, "some instance needs more than one sheet");
}
