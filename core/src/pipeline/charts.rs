//! The charts between the merge and the packing: which chart each face packs with, the faces'
//! 3-D areas, and the changes of topology made on the way (the rigid split, the untangle, the
//! detachment of clashing faces), handing out the packing's [`LayoutInput`] view.

use std::collections::{HashMap, HashSet};

use super::PipelineError;
use crate::defrag::{EnergyBudget, MergedLayout, UntangleOptions, UntangleReport, untangle_charts};
use crate::index::NONE;
use crate::model::Model;
use crate::pack::palette::{self, PaletteFace};
use crate::pack::{LayoutInput, PackOptions, PackedLayout, RigidSplitReport, anchor_faces};
use crate::plugin::LocalSolver;
use crate::topology::Topology;
use crate::vec3::triangle_area;

/// The chart of every face for packing (`NONE` for faces left out), with what packing
/// needs beside it.
pub(super) struct PackingCharts {
    pub face_chart: Vec<u32>,
    /// Number of charts (ids `0..n`).
    pub n: usize,
    pub face_area_3d: Vec<f64>,
    /// Faces left out of packing (no usable UVs or no sheet).
    pub unpacked: u64,
    /// The UV vertex of every corner, as plain numbers; rebuilt whenever the topology changes.
    corner_vert: Vec<u32>,
}

impl PackingCharts {
    /// The merged layout's charts; faces without usable UVs or without a sheet are left out.
    pub fn new(model: &Model, topo: &Topology, layout: &MergedLayout) -> Self {
        let (face_chart, unpacked) = packing_charts(topo, layout, model.sheets.len());
        let face_area_3d =
            model.face_ids().map(|f| triangle_area(model.face_positions(f))).collect();
        Self { face_chart, n: layout.n_charts, face_area_3d, unpacked, corner_vert: Vec::new() }
    }

    /// Rebuilds the corner table after a change of topology.
    fn refresh(&mut self, topo: &Topology) {
        self.corner_vert = topo.corner_uv.iter().map(|v| v.0).collect();
    }

    /// The packing stage's view of the charts in `topo`.
    pub fn layout_input<'a>(
        &'a mut self,
        topo: &'a Topology,
        input_sheet_sizes: &'a [(u32, u32)],
    ) -> LayoutInput<'a> {
        self.refresh(topo);
        layout_input(
            topo,
            &self.corner_vert,
            &self.face_chart,
            &self.face_area_3d,
            self.n,
            input_sheet_sizes,
        )
    }

    /// Makes the qualifying rigid groups charts of their own (see `rigid_split`).
    pub fn split_rigid(
        &mut self,
        topo: &mut Topology,
        input_sheet_sizes: &[(u32, u32)],
        opts: &PackOptions,
        border_len: f64,
    ) -> Result<RigidSplitReport, PipelineError> {
        super::rigid_split::split_rigid_groups(
            topo,
            &mut self.face_chart,
            &mut self.n,
            &self.face_area_3d,
            input_sheet_sizes,
            opts,
            border_len,
        )
    }

    /// Repairs inherited folds and self-overlaps of the charts, keeping the faces the packing
    /// would copy verbatim (its anchors) in place.
    pub fn untangle(
        &mut self,
        topo: &mut Topology,
        input_sheet_sizes: &[(u32, u32)],
        pack: &PackOptions,
        solvers: &mut [Box<dyn LocalSolver>],
        opts: &UntangleOptions,
        budget: EnergyBudget,
    ) -> Result<UntangleReport, PipelineError> {
        let anchored = anchor_faces(&self.layout_input(topo, input_sheet_sizes), pack)?;
        let (face_chart, n) = (&self.face_chart, self.n);
        Ok(untangle_charts(topo, face_chart, n, &anchored, solvers, opts, Some(budget)))
    }

    /// Takes the faces without input UV area that no face with area holds by an input UV edge out
    /// of their charts, for the palette (see `pack::palette`); returns them in face order with
    /// the number of them that span a segment rather than a point.
    ///
    /// A face that shares an input UV edge with a face of positive area is a sliver inside a
    /// chart: it lies on that chart's texels wherever the chart goes, so its colour is the
    /// chart's along it, and cutting it out would only open a seam. The others are the points
    /// (and lines) exporters collapse unseen faces onto, which show one input colour that no
    /// chart around their new place holds.
    pub fn take_palette_faces(&mut self, topo: &Topology) -> (Vec<PaletteFace>, usize) {
        let tri = |f: usize| [0, 1, 2].map(|k| topo.orig_uv[3 * f + k]);
        let candidate = |f: usize| self.face_chart[f] != NONE && palette::zero_uv_area(tri(f));
        // Input UV vertices of the candidates' corners, keyed as the input welds them.
        let key = |c: usize| {
            let uv = topo.orig_uv[c];
            (topo.corner_pos[c].0, topo.face_sheet[c / 3], uv[0].to_bits(), uv[1].to_bits())
        };
        let mut ids: HashMap<(u32, u32, u64, u64), u32> = HashMap::new();
        for f in (0..self.face_chart.len()).filter(|&f| candidate(f)) {
            for c in 3 * f..3 * f + 3 {
                let next = ids.len() as u32;
                ids.entry(key(c)).or_insert(next);
            }
        }
        // Input UV edges between those vertices that some face with area has.
        let mut held: HashSet<(u32, u32)> = HashSet::new();
        for f in (0..self.face_chart.len()).filter(|&f| self.face_chart[f] != NONE) {
            if candidate(f) {
                continue;
            }
            let corners = [0, 1, 2].map(|k| ids.get(&key(3 * f + k)).copied());
            for k in 0..3 {
                if let (Some(a), Some(b)) = (corners[k], corners[(k + 1) % 3]) {
                    held.insert((a.min(b), a.max(b)));
                }
            }
        }
        let mut out = Vec::new();
        let mut segments = 0;
        let candidates: Vec<usize> = (0..self.face_chart.len()).filter(|&f| candidate(f)).collect();
        for f in candidates {
            let v = [0, 1, 2].map(|k| ids[&key(3 * f + k)]);
            if (0..3).any(|k| held.contains(&(v[k].min(v[(k + 1) % 3]), v[k].max(v[(k + 1) % 3]))))
            {
                continue;
            }
            let t = tri(f);
            segments += usize::from(t.iter().any(|p| p != &t[0]));
            let (ends, along) = palette::colour_segment(t);
            out.push(PaletteFace { face: f as u32, src_sheet: topo.face_sheet[f], ends, along });
        }
        for p in &out {
            self.face_chart[p.face as usize] = NONE;
        }
        (out, segments)
    }

    /// Takes the specks out of their charts for the palette (see `pack::palette`): charts whose
    /// faces cover less than `max_area` texels² of input UV area and fit, in the input, within
    /// one texel each way. Such a chart is a fragment the reconstruction left floating (or a
    /// sliver the merge could not join), and it shows one input colour, as a point face does:
    /// all its faces are mapped onto one block painted with the input's colour at the speck's
    /// centroid, instead of costing a chart of its own with its padding. Returns them in face
    /// order with the number of charts they made.
    pub fn take_specks(&mut self, topo: &Topology, max_area: f64) -> (Vec<PaletteFace>, usize) {
        if max_area <= 0.0 {
            return (Vec::new(), 0);
        }
        let tri = |f: usize| [0, 1, 2].map(|k| topo.orig_uv[3 * f + k]);
        let mut charts = vec![SpeckTally::default(); self.n];
        for (f, &c) in self.face_chart.iter().enumerate() {
            if c != NONE {
                charts[c as usize].add(tri(f), topo.face_sheet[f]);
            }
        }
        let speck = |t: &SpeckTally| t.is_speck(max_area);
        let mut out = Vec::new();
        for (f, c) in self.face_chart.iter_mut().enumerate() {
            if *c == NONE || !speck(&charts[*c as usize]) {
                continue;
            }
            let centre = charts[*c as usize].centroid();
            out.push(PaletteFace {
                face: f as u32,
                src_sheet: topo.face_sheet[f],
                ends: [centre, centre],
                along: [0.5; 3],
            });
            *c = NONE;
        }
        (out, charts.iter().filter(|t| speck(t)).count())
    }

    /// The last resort for texel clashes the sub-texel moves could not separate: one face of
    /// every such pair (`both`: each face of every pair) becomes a chart of its own. Returns how
    /// many faces were detached.
    pub fn detach_clashes(
        &mut self,
        topo: &mut Topology,
        packed: &PackedLayout,
        both: bool,
    ) -> usize {
        let detach = if both {
            let mut faces: Vec<u32> = packed.clashing_pairs.iter().flatten().copied().collect();
            faces.sort_unstable();
            faces.dedup();
            faces
        } else {
            faces_to_detach(packed, topo)
        };
        for &f in &detach {
            topo.detach_faces(&[f]);
            self.face_chart[f as usize] = self.n as u32;
            self.n += 1;
        }
        detach.len()
    }
}

/// The chart of each face for packing (`NONE` for faces without usable UVs or without a
/// sheet, which packing leaves out) and the number of such faces.
fn packing_charts(t: &Topology, layout: &MergedLayout, n_sheets: usize) -> (Vec<u32>, u64) {
    let mut unpacked = 0;
    let chart = (0..t.face_flags.len())
        .map(|f| {
            if t.face_flags[f].has_usable_uv() && (t.face_sheet[f] as usize) < n_sheets {
                layout.face_chart[f]
            } else {
                unpacked += 1;
                NONE
            }
        })
        .collect();
    (chart, unpacked)
}

/// One face of every pair the texel-clash step left clashing, to be cut out of its chart: a face
/// copied verbatim keeps its place (the other is taken), then the smaller UV area goes; a face
/// already taken settles every pair it is in. In pair order, so the choice is deterministic.
fn faces_to_detach(packed: &PackedLayout, topo: &Topology) -> Vec<u32> {
    let area = |f: u32| {
        let [a, b, c] = [0, 1, 2].map(|k| topo.uv_pos[topo.corner_uv[3 * f as usize + k].idx()]);
        crate::geometry::signed_area2([a, b, c]).abs()
    };
    let mut taken: Vec<u32> = Vec::new();
    for &[f, g] in &packed.clashing_pairs {
        if taken.contains(&f) || taken.contains(&g) {
            continue;
        }
        let keep_f = (packed.face_preserved[f as usize], area(f))
            > (packed.face_preserved[g as usize], area(g));
        taken.push(if keep_f { g } else { f });
    }
    taken
}

/// The packing stage's view of the merged layout in `topo`.
pub(super) fn layout_input<'a>(
    topo: &'a Topology,
    corner_vert: &'a [u32],
    face_chart: &'a [u32],
    face_area_3d: &'a [f64],
    n_charts: usize,
    input_sheet_sizes: &'a [(u32, u32)],
) -> LayoutInput<'a> {
    LayoutInput {
        corner_vert,
        vert_uv: &topo.uv_pos,
        orig_uv: &topo.orig_uv,
        face_chart,
        face_sheet: &topo.face_sheet,
        face_area_3d,
        n_charts,
        input_sheet_sizes,
    }
}

/// What [`PackingCharts::take_specks`] needs of a chart: its input UV area, moment, extent and
/// sheet.
#[derive(Clone, Copy, Debug)]
struct SpeckTally {
    area: f64,
    moment: [f64; 2],
    lo: [f64; 2],
    hi: [f64; 2],
    /// The input sheet of its faces; `NONE` before the first face, `NONE - 1` once they differ.
    sheet: u32,
}

impl Default for SpeckTally {
    fn default() -> Self {
        Self {
            area: 0.0,
            moment: [0.0; 2],
            lo: [f64::INFINITY; 2],
            hi: [f64::NEG_INFINITY; 2],
            sheet: NONE,
        }
    }
}

impl SpeckTally {
    const MIXED: u32 = NONE - 1;

    fn add(&mut self, t: [[f64; 2]; 3], sheet: u32) {
        let a = 0.5 * crate::geometry::signed_area2(t).abs();
        for k in 0..2 {
            self.moment[k] += a * (t[0][k] + t[1][k] + t[2][k]) / 3.0;
            self.lo[k] = t.iter().map(|p| p[k]).fold(self.lo[k], f64::min);
            self.hi[k] = t.iter().map(|p| p[k]).fold(self.hi[k], f64::max);
        }
        self.area += a;
        self.sheet = if self.sheet == NONE || self.sheet == sheet { sheet } else { Self::MIXED };
    }

    /// A chart with some area (one without any is made of point faces, which the palette takes
    /// anyway) but less than `max_area`, within one texel each way, on one sheet.
    fn is_speck(&self, max_area: f64) -> bool {
        self.area >= crate::metrics::DEGEN_AREA_TEXELS
            && self.area < max_area
            && (0..2).all(|k| self.hi[k] - self.lo[k] <= 1.0)
            && self.sheet != Self::MIXED
    }

    fn centroid(&self) -> [f64; 2] {
        self.moment.map(|m| m / self.area)
    }
}
