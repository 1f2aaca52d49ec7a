//! The `Pack` stage of `defrag`: the rigid split, the repair of inherited folds within the
//! distortion budget, the packer (again after detaching the faces of texel clashes), the palette,
//! and the warnings the packing raises.

use super::{DefragConfig, Loaded, Plugins, output_format};
use crate::defrag::{EnergyBudget, UntangleReport};
use crate::index::NONE;
use crate::pack::palette::{self, Palette, PaletteFace, PaletteSpace};
use crate::pack::{PackOptions, PackReport, PackedLayout, pack_layout};
use crate::pipeline::PipelineError;
use crate::pipeline::charts::PackingCharts;
use crate::timing::ms;
use crate::topology::Topology;
use crate::warnings::{Warning, WarningCode};
use std::time::Instant;

/// What the packing reads of the merge: the UV border length and the distortion budget left.
#[derive(Clone, Copy)]
pub(super) struct Merged {
    pub border_len: f64,
    pub budget: EnergyBudget,
}

/// How many times the atlas is packed again for faces detached for texel clashes; the last
/// round detaches both faces of every pair left.
const MAX_DETACH_ROUNDS: usize = 4;

/// The warnings of a packing: sheets over a fixed size, faces detached for texel clashes,
/// clashes left, and an atlas that outgrew its input at a `texel_scale` of at most 1 (above 1 it
/// grows by design).
pub(super) fn pack_warnings(report: &PackReport, texel_scale: f64) -> Vec<Warning> {
    let mut warnings = Vec::new();
    if report.sheets_off_size > 0 {
        warnings.push(Warning::new(
            WarningCode::SheetSizeExceeded,
            format!(
                "--sheet-size: {} of {} output sheets are larger than the fixed size, because a \
                 chart does not fit on a sheet of that size (charts {:?})",
                report.sheets_off_size, report.sheets, report.oversized_charts
            ),
        ));
    }
    if report.faces_detached > 0 {
        warnings.push(Warning::new(
            WarningCode::FacesDetached,
            format!(
                "{} faces were cut out of their charts into charts of their own and the atlas \
                 packed again (rounds: {}), because the texels they cover would otherwise be \
                 shared with another face of their chart",
                report.faces_detached, report.detach_rounds
            ),
        ));
    }
    if report.texels > report.input_texels && texel_scale <= 1.0 {
        let grew = report.texels as f64 / report.input_texels.max(1) as f64 - 1.0;
        warnings.push(Warning::new(
            WarningCode::AtlasGrew,
            format!(
                "the {} output sheets hold {} texels, {:.1}% more than the input's {}: the packer \
                 found no packing of the {} charts within the input's texel count (sheet limit \
                 {}x{}, {} other shapes of its area tried)",
                report.sheets,
                report.texels,
                100.0 * grew,
                report.input_texels,
                report.charts,
                report.max_sheet_size.0,
                report.max_sheet_size.1,
                report.sheet_shapes_tried
            ),
        ));
    }
    if report.texel_clashes_left > 0 {
        warnings.push(Warning::new(
            WarningCode::TexelClashesLeft,
            format!(
                "{} pairs of faces share texels in the output that they did not share in the \
                 input: each shows the other's colour there",
                report.texel_clashes_left
            ),
        ));
    }
    warnings
}

/// The packing: the rigid split, the repair of inherited folds, the packer, and once more
/// after detaching the faces of texel clashes the packing could not separate.
pub(super) fn pack_stage(
    topo: &mut Topology,
    charts: &mut PackingCharts,
    loaded: &Loaded,
    plugins: &mut Plugins,
    cfg: &DefragConfig,
    merged: Merged,
) -> Result<(PackedLayout, Palette, Option<UntangleReport>), PipelineError> {
    let sizes = &loaded.input_sheet_sizes;
    let t = Instant::now();
    let (mut palette_faces, segments) = charts.take_palette_faces(topo);
    let (specks, speck_charts) = charts.take_specks(topo, cfg.pack.speck_area);
    let speck_faces = specks.len();
    palette_faces.extend(specks);
    palette_faces.sort_unstable_by_key(|p| p.face);
    let palette_faces_ms = ms(t);
    let t = Instant::now();
    let rigid_split = if cfg.pack.split_rigid_ratio > 0.0 {
        Some(charts.split_rigid(topo, sizes, &cfg.pack, merged.border_len)?)
    } else {
        None
    };
    let split_rigid_ms = ms(t);
    let t = Instant::now();
    let mut untangled = None;
    if let (Some(opts), false) = (&cfg.untangle, plugins.untangle_solvers.is_empty()) {
        let solvers = &mut plugins.untangle_solvers;
        untangled = Some(charts.untangle(topo, sizes, &cfg.pack, solvers, opts, merged.budget)?);
    }
    let untangle_ms = ms(t);
    let packer = plugins.packer.as_ref();
    let mut packed = pack_layout(&charts.layout_input(topo, sizes), packer, &cfg.pack)?;
    // A packing of other charts puts every face at another sub-texel offset, so a new packing
    // may clash where the last did not: detach and pack again until none is left, cutting out
    // both faces of every pair in the last round (a face alone in its chart clashes with no
    // other).
    let mut round = 0;
    let mut detach_ms = 0.0;
    while !packed.clashing_pairs.is_empty() && round < MAX_DETACH_ROUNDS {
        round += 1;
        let both = round == MAX_DETACH_ROUNDS;
        let t = Instant::now();
        let detached = charts.detach_clashes(topo, &packed, both);
        detach_ms += ms(t);
        let earlier = packed.report;
        packed = pack_layout(&charts.layout_input(topo, sizes), packer, &cfg.pack)?;
        add_earlier_attempt(&mut packed.report, &earlier, detached);
    }
    if let Some(split) = rigid_split {
        packed.report.rigid_split = split;
    }
    let format = output_format(cfg, &loaded.model)?;
    let space = PaletteSpace {
        side: palette::block_side(format, cfg.jpeg_quality, cfg.lossy_webp),
        padding: cfg.pack.padding,
        max_sheet_size: packed.report.max_sheet_size,
        may_widen: cfg.pack.sheet_size.is_none(),
    };
    let t = Instant::now();
    let palette =
        place_palette_blocks(topo, charts, &mut packed, &palette_faces, segments, space, &cfg.pack);
    let r = &mut packed.report;
    (r.palette.speck_charts, r.palette.speck_faces) = (speck_charts, speck_faces);
    (r.palette_faces_ms, r.split_rigid_ms, r.untangle_ms) =
        (palette_faces_ms, split_rigid_ms, untangle_ms);
    (r.detach_ms, r.palette_ms) = (detach_ms, ms(t));
    Ok((packed, palette, untangled))
}

/// Places the palette (see `pack::palette`) around the packed charts, and brings the packing's
/// sheet figures up to date with the sheets it widened or added. Those sheets get the sides the
/// options allow (`--sheet-size`, `--pow2`, `--align`), as the packer's own sheets do: the blocks
/// sit at the top left of their cells, so a sheet that grows keeps them in place.
fn place_palette_blocks(
    topo: &Topology,
    charts: &PackingCharts,
    packed: &mut PackedLayout,
    faces: &[PaletteFace],
    segments: usize,
    space: PaletteSpace,
    opts: &PackOptions,
) -> Palette {
    let tris = (0..charts.face_chart.len())
        .filter(|&f| charts.face_chart[f] != NONE && packed.face_sheet[f] != NONE)
        .map(|f| {
            let tri = [0, 1, 2].map(|k| packed.vert_uv[topo.corner_uv[3 * f + k].idx()]);
            (packed.face_sheet[f], tri)
        });
    let before = packed.sheet_sizes.clone();
    let mut palette = palette::place_palette(faces, segments, tris, &mut packed.sheet_sizes, space);
    let texels = |sizes: &[(u32, u32)]| -> u64 {
        sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum()
    };
    for (s, size) in packed.sheet_sizes.iter_mut().enumerate() {
        if before.get(s) != Some(size) {
            *size = crate::pack::output_sheet_size(*size, opts).0;
        }
    }
    palette.report.texels_added = texels(&packed.sheet_sizes) - texels(&before);
    let r = &mut packed.report;
    r.palette = palette.report;
    if palette.report.texels_added > 0 {
        let before = r.texels;
        r.texels += palette.report.texels_added;
        r.sheets = packed.sheet_sizes.len();
        r.occupancy *= before as f64 / r.texels as f64;
    }
    palette
}

/// Folds the report of the packing before the clash detachment into the final one.
fn add_earlier_attempt(r: &mut PackReport, earlier: &PackReport, detached: usize) {
    r.faces_detached = earlier.faces_detached + detached;
    r.detach_rounds = earlier.detach_rounds + 1;
    // The clashes the first packing found; those left are the last packing's.
    r.texel_clashes = earlier.texel_clashes;
    r.texel_clash_vertices_moved += earlier.texel_clash_vertices_moved;
    for (ms, earlier_ms) in [
        (&mut r.anchors_ms, earlier.anchors_ms),
        (&mut r.texel_clash_ms, earlier.texel_clash_ms),
        (&mut r.footprints_ms, earlier.footprints_ms),
        (&mut r.packing_ms, earlier.packing_ms),
        (&mut r.finish_ms, earlier.finish_ms),
    ] {
        *ms += earlier_ms;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grew(report: &PackReport, texel_scale: f64) -> bool {
        pack_warnings(report, texel_scale).iter().any(|w| w.code == WarningCode::AtlasGrew)
    }

    #[test]
    fn an_atlas_larger_than_its_input_warns_unless_the_texel_scale_asks_for_it() {
        let report = PackReport {
            texels: 5_000_000,
            input_texels: 4_194_304,
            sheets: 2,
            ..PackReport::default()
        };
        assert!(grew(&report, 1.0));
        assert!(grew(&report, 0.5));
        assert!(!grew(&report, 2.0), "a texel scale above 1 grows the atlas by design");
        let smaller = PackReport { texels: 4_000_000, ..report };
        assert!(!grew(&smaller, 1.0));
    }
}
