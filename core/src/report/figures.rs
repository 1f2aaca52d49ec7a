//! The figures of a report and the headline that says them in plain words: sheet sizes and the
//! texel change, charts, the share of the surface copied texel for texel, colour PSNR, flips,
//! overlaps and lost faces.

use serde::Serialize;

use super::colour::ColourFidelity;
use crate::metrics::AtlasStats;
use crate::pipeline::defrag::DefragReport;

/// The atlas figures of one side of a report.
#[derive(Clone, Debug, Serialize)]
pub struct SideFigures {
    pub model: String,
    pub faces: u64,
    /// Size of every sheet whose size is known.
    pub sheet_sizes: Vec<(u32, u32)>,
    pub texels: u64,
    /// Edge-connected charts that cover some UV area.
    pub charts: u64,
    pub uv_border_texels: f64,
    pub solidity: Option<f64>,
    pub vertex_replication: Option<f64>,
    pub flipped_faces: u64,
    pub overlap_texels: Option<u64>,
    /// Faces of the edge charts without UV area (a point or a line of the texture each), counted
    /// apart from the charts.
    pub point_faces: u64,
    pub faces_without_texture: u64,
}

impl SideFigures {
    pub fn new(model: String, s: &AtlasStats) -> Self {
        let sheet_sizes =
            s.texture_sizes.iter().filter_map(|t| Some((t.width?, t.height?))).collect();
        Self {
            model,
            faces: s.faces,
            sheet_sizes,
            texels: s.total_texels,
            charts: s.charts_edge_with_area,
            uv_border_texels: s.uv_boundary_length_texels,
            solidity: s.atlas_solidity,
            vertex_replication: s.vertex_replication,
            flipped_faces: s.uv_flipped_faces,
            overlap_texels: s.overlap_texels,
            point_faces: s.point_faces,
            faces_without_texture: s.faces_without_texture,
        }
    }
}

/// Everything a report measures, as written to `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct Figures {
    pub headline: String,
    /// `None` when there is no textured input (a `build` report).
    pub before: Option<SideFigures>,
    pub after: SideFigures,
    /// Faces whose output triangle is the input's under a whole-texel grid map.
    pub preserved_faces: Option<u64>,
    /// Their share of the 3-D area of the faces textured on both sides.
    pub preserved_area_fraction: Option<f64>,
    /// Mean isometric distortion of the output UVs against the input's (weighted by input texel
    /// area; 0 for an exact copy).
    pub mean_distortion: Option<f64>,
    /// Faces textured in the input and not in the output.
    pub faces_lost: Option<u64>,
    /// Colour PSNR of the output against the input at points drawn on the surface.
    pub colour: Option<ColourFidelity>,
}

impl Figures {
    /// The figures a defrag run's report already holds (no colour comparison), for the terminal.
    pub fn from_defrag(r: &DefragReport) -> Self {
        let before = SideFigures::new(r.input.display().to_string(), &r.input_stats);
        let after = SideFigures::new(r.output.display().to_string(), &r.output_stats);
        let lost = after.faces_without_texture.saturating_sub(before.faces_without_texture)
            + before.faces.saturating_sub(after.faces);
        let mut f = Self {
            headline: String::new(),
            before: Some(before),
            after,
            preserved_faces: r.pack.as_ref().map(|p| p.preserved_faces as u64),
            preserved_area_fraction: r.pack.as_ref().map(|p| p.preserved_area_fraction),
            mean_distortion: Some(r.distortion),
            faces_lost: Some(lost),
            colour: None,
        };
        f.headline = headline(&f);
        f
    }
}

/// Sheet sizes in a few characters: `4096²`, `1208×1297`, `16 × 8192²`, or `5 sheets`.
pub fn fmt_sheets(sizes: &[(u32, u32)]) -> String {
    let one = |&(w, h): &(u32, u32)| if w == h { format!("{w}²") } else { format!("{w}×{h}") };
    match sizes {
        [] => "no sheet".into(),
        [s] => one(s),
        [s, rest @ ..] if rest.iter().all(|r| r == s) => format!("{} × {}", sizes.len(), one(s)),
        _ => format!("{} sheets", sizes.len()),
    }
}

/// A count in a few characters: `950`, `12.3 k`, `4.1 M`, `1.07 G`.
pub fn fmt_count(n: u64) -> String {
    let x = n as f64;
    match n {
        0..1_000 => n.to_string(),
        1_000..1_000_000 => format!("{:.1} k", x / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1} M", x / 1e6),
        _ => format!("{:.2} G", x / 1e9),
    }
}

/// A signed percentage with a true minus sign: `−91%`, `+4%`.
fn fmt_change(before: u64, after: u64) -> Option<String> {
    if before == 0 {
        return None;
    }
    let p = (after as f64 / before as f64 - 1.0) * 100.0;
    let r = p.round();
    Some(if r < 0.0 { format!("−{}%", -r) } else { format!("+{r}%") })
}

/// The headline in plain words: sheet sizes and the texel change, charts before and after, the
/// share of the surface copied texel for texel, the colour PSNR against the input, new defects
/// and lost faces, each only when it was measured.
pub fn headline(f: &Figures) -> String {
    let a = &f.after;
    let mut parts = Vec::new();
    match &f.before {
        Some(b) => {
            let mut s = format!("{} → {}", fmt_sheets(&b.sheet_sizes), fmt_sheets(&a.sheet_sizes));
            if let Some(c) = fmt_change(b.texels, a.texels) {
                s += &format!(" ({c} texels)");
            }
            parts.push(s);
            parts.push(format!("charts {} → {}", b.charts, a.charts));
            if b.point_faces + a.point_faces > 0 {
                parts.push(format!("point faces {} → {}", b.point_faces, a.point_faces));
            }
        }
        None => {
            parts.push(format!("{} ({} texels)", fmt_sheets(&a.sheet_sizes), fmt_count(a.texels)));
            parts.push(format!("{} charts", a.charts));
            if a.point_faces > 0 {
                parts.push(format!("{} point faces", a.point_faces));
            }
        }
    }
    if let Some(p) = f.preserved_area_fraction {
        parts.push(format!("{:.0}% of the surface copied texel for texel", 100.0 * p));
    }
    if let Some(db) = f.colour.and_then(|c| c.all.psnr_db) {
        parts.push(if db.is_finite() {
            format!("colour PSNR {db:.1} dB against the input")
        } else {
            "colours identical to the input".into()
        });
    }
    parts.push(defects(f));
    if let Some(lost) = f.faces_lost {
        parts.push(match lost {
            0 => "no face lost".into(),
            n => format!("{n} faces lost their texture"),
        });
    }
    parts.join(", ")
}

/// Flips and overlaps in words: none, or their counts before and after.
fn defects(f: &Figures) -> String {
    let a = &f.after;
    let b = f.before.as_ref();
    let flips_fine = a.flipped_faces == 0 || b.is_some_and(|b| a.flipped_faces <= b.flipped_faces);
    let overlaps_fine = match (a.overlap_texels, b.and_then(|b| b.overlap_texels)) {
        (None, _) | (Some(0), _) => true,
        (Some(x), Some(y)) => x <= y,
        (Some(_), None) => false,
    };
    let checked = if a.overlap_texels.is_some() { "flips or overlaps" } else { "flips" };
    if a.flipped_faces == 0 && a.overlap_texels.unwrap_or(0) == 0 {
        return format!("no {checked}");
    }
    let mut s = Vec::new();
    let before = |x: Option<u64>| x.map_or(String::new(), |x| format!("{x} → "));
    if a.flipped_faces > 0 {
        s.push(format!("flipped faces {}{}", before(b.map(|b| b.flipped_faces)), a.flipped_faces));
    }
    if let Some(o) = a.overlap_texels.filter(|&o| o > 0) {
        s.push(format!("overlapping texels {}{o}", before(b.and_then(|b| b.overlap_texels))));
    }
    let verdict = if flips_fine && overlaps_fine { " (fewer than in the input)" } else { "" };
    s.join(", ") + verdict
}

/// One line per figure: what it means and which way is better.
pub const EXPLANATIONS: &[(&str, &str)] = &[
    (
        "Sheets and texels",
        "the texture memory; fewer texels is better, as long as the colour holds.",
    ),
    (
        "Charts",
        "the pieces of UV area the texture is cut into (edge-connected); fewer means fewer seams, less colour bleeding at seams and less space lost to gutters. Point faces (no UV area: a point or a line of the texture, one colour each) are counted apart.",
    ),
    (
        "Copied texel for texel",
        "the share of the surface whose texels were moved whole, not interpolated; those keep the input's sharpness exactly. Higher is better.",
    ),
    (
        "Colour PSNR",
        "the colour difference against the input at random points of the surface; higher is better, above about 40 dB differences are hard to see.",
    ),
    (
        "Distortion",
        "how much the output UVs stretch the input's (isometric energy, 0 = the same shape); lower is better.",
    ),
    (
        "Solidity",
        "how compact the atlas is: the perimeter of a disk of the charts' area over their border length, 1 for one disk; higher is better.",
    ),
    (
        "Vertex replication",
        "UV vertices per 3-D vertex; every seam duplicates vertices, so closer to 1 is better.",
    ),
    (
        "Flips and overlaps",
        "UV triangles turned over, and texels two faces claim: both show wrong colours; 0 is right.",
    ),
];

#[cfg(test)]
mod tests {
    use super::*;

    fn side(sizes: Vec<(u32, u32)>, charts: u64, flipped: u64) -> SideFigures {
        SideFigures {
            model: "m".into(),
            faces: 10,
            texels: sizes.iter().map(|&(w, h)| u64::from(w) * u64::from(h)).sum(),
            sheet_sizes: sizes,
            charts,
            uv_border_texels: 1.0,
            solidity: None,
            vertex_replication: None,
            flipped_faces: flipped,
            overlap_texels: Some(0),
            point_faces: 0,
            faces_without_texture: 0,
        }
    }

    #[test]
    fn headline_says_sizes_texel_change_and_charts() {
        let f = Figures {
            headline: String::new(),
            before: Some(side(vec![(4096, 4096)], 711, 3)),
            after: side(vec![(1208, 1297)], 92, 0),
            preserved_faces: Some(5),
            preserved_area_fraction: Some(0.15),
            mean_distortion: Some(0.02),
            faces_lost: Some(0),
            colour: None,
        };
        assert_eq!(
            headline(&f),
            "4096² → 1208×1297 (−91% texels), charts 711 → 92, 15% of the surface copied texel \
             for texel, no flips or overlaps, no face lost"
        );
    }

    #[test]
    fn sheets_and_counts_are_short() {
        assert_eq!(fmt_sheets(&[(8192, 8192); 16]), "16 × 8192²");
        assert_eq!(fmt_sheets(&[(10, 20), (30, 40)]), "2 sheets");
        assert_eq!(fmt_count(1_073_741_824), "1.07 G");
    }
}
