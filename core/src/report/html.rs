//! `index.html`: one self-contained page (inline CSS, no script or font from the network) showing
//! the headline, what each figure means, the pictures of every sheet before and after, the plots
//! and a table of the figures. Pictures are files beside the page.

use std::fmt::Write as _;

use super::figures::{EXPLANATIONS, Figures, SideFigures, fmt_count, fmt_sheets};
use super::{ReportSummary, SheetPictures};

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:24px auto;max-width:1400px;\
color:#222;background:#fff;padding:0 16px}h1{font-size:20px;color:#555;margin-bottom:4px}\
p.headline{font-size:26px;font-weight:600;line-height:1.35;margin:8px 0 16px}\
dl{display:grid;grid-template-columns:max-content 1fr;gap:4px 16px;font-size:14px}\
dt{font-weight:600}dd{margin:0}.cols{display:grid;grid-template-columns:1fr 1fr;gap:24px}\
figure{margin:0 0 24px}figure img{max-width:100%;height:auto;border:1px solid #ccc;\
image-rendering:pixelated;background:#fafafa}figcaption{font-size:13px;color:#555}\
.pair{display:grid;grid-template-columns:1fr 1fr;gap:8px}table{border-collapse:collapse;\
font-size:14px}td,th{border-bottom:1px solid #ddd;padding:4px 12px;text-align:right}\
td:first-child,th:first-child{text-align:left}.warn{color:#a00}.key span{display:inline-block;\
width:12px;height:12px;margin:0 4px 0 12px;vertical-align:middle}";

/// Escapes text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The whole page.
pub fn page(r: &ReportSummary) -> String {
    let f = &r.figures;
    let mut h = String::with_capacity(16 * 1024);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n<h1>{}</h1>\n\
         <p class=\"headline\">{}</p>\n",
        esc(&r.title),
        esc(&r.title),
        esc(&f.headline)
    );
    for w in &r.warnings {
        let _ = writeln!(h, "<p class=\"warn\">{}</p>", esc(w));
    }
    h += "<dl>\n";
    for (name, text) in EXPLANATIONS {
        let _ = writeln!(h, "<dt>{}</dt><dd>{}</dd>", esc(name), esc(text));
    }
    h += "</dl>\n";
    sheets_section(&mut h, r);
    h += "<h2>Plots</h2>\n<div class=\"cols\">\n";
    for (file, caption) in &r.plots {
        let _ = writeln!(
            h,
            "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
            esc(file),
            esc(caption),
            esc(caption)
        );
    }
    h += "</div>\n";
    figures_table(&mut h, f);
    h += "<p>All figures: <a href=\"report.json\">report.json</a>.</p>\n";
    // Marks on the page whether every picture loaded, for people and for the browser test.
    h += "<p id=\"pictures\"></p><script>window.addEventListener('load',function(){\
          var i=document.images,n=0;for(var k=0;k<i.length;k++){if(i[k].complete&&\
          i[k].naturalWidth>0)n++;}var p=document.getElementById('pictures');\
          p.dataset.loaded=n;p.dataset.total=i.length;\
          if(n<i.length){p.className='warn';p.textContent=(i.length-n)+' pictures did not load';}\
          });</script>\n</body></html>\n";
    h
}

fn sheets_section(h: &mut String, r: &ReportSummary) {
    *h += "<h2>Sheets</h2>\n<p class=\"key\">Atlas: every chart in its own colour, seams dark, \
          faces with no UV area as magenta dots. Texture: \
          <span style=\"background:#1e64ff\"></span>texels copied texel for texel \
          <span style=\"background:#ff8200\"></span>texels resampled (interpolated) \
          <span style=\"background:#e600c8\"></span>faces with no UV area; unused texels pale.</p>\n";
    let with_before = !r.before_sheets.is_empty();
    if with_before {
        *h += "<div class=\"cols\"><div><h3>Before</h3>\n";
        for s in &r.before_sheets {
            sheet(h, "before", s);
        }
        *h += "</div><div><h3>After</h3>\n";
    }
    for s in &r.after_sheets {
        sheet(h, "after", s);
    }
    if with_before {
        *h += "</div></div>\n";
    }
}

fn sheet(h: &mut String, tag: &str, s: &SheetPictures) {
    let scale = if s.preview.0 < s.size.0 {
        format!(", shown at 1:{}", s.size.0.div_ceil(s.preview.0))
    } else {
        String::new()
    };
    let _ = write!(h, "<figure><div class=\"pair\">");
    for file in [Some(&s.atlas), s.texture.as_ref(), s.heat.as_ref()].into_iter().flatten() {
        let _ = write!(
            h,
            "<img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\">",
            esc(file),
            s.preview.0,
            s.preview.1,
            esc(file)
        );
    }
    let heat = if s.heat.is_some() {
        "; third: distortion against the input, blue exact to red strongly stretched"
    } else {
        ""
    };
    let _ = writeln!(
        h,
        "</div><figcaption>{tag} sheet {} ({}×{}{scale}): atlas, texture{heat}</figcaption></figure>",
        s.sheet, s.size.0, s.size.1
    );
}

fn figures_table(h: &mut String, f: &Figures) {
    let opt = |x: Option<f64>, d: usize| x.map_or("–".to_string(), |x| format!("{x:.d$}"));
    let row = |h: &mut String, name: &str, get: &dyn Fn(&SideFigures) -> String| {
        let b = f.before.as_ref().map_or("–".to_string(), get);
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(name),
            esc(&b),
            esc(&get(&f.after))
        );
    };
    *h += "<h2>Figures</h2>\n<table><tr><th></th><th>before</th><th>after</th></tr>\n";
    row(h, "sheets", &|s| fmt_sheets(&s.sheet_sizes));
    row(h, "texels", &|s| fmt_count(s.texels));
    row(h, "charts with area", &|s| s.charts.to_string());
    row(h, "UV border (texels)", &|s| format!("{:.0}", s.uv_border_texels));
    row(h, "solidity", &|s| opt(s.solidity, 4));
    row(h, "vertex replication", &|s| opt(s.vertex_replication, 3));
    row(h, "flipped faces", &|s| s.flipped_faces.to_string());
    row(h, "overlapping texels", &|s| {
        s.overlap_texels.map_or("not measured".into(), |x| x.to_string())
    });
    row(h, "point faces (no UV area)", &|s| s.point_faces.to_string());
    *h += "</table>\n<table>\n";
    let mut line = |name: &str, value: String| {
        let _ = writeln!(h, "<tr><td>{}</td><td>{}</td></tr>", esc(name), esc(&value));
    };
    if let (Some(p), Some(n)) = (f.preserved_area_fraction, f.preserved_faces) {
        line("copied texel for texel", format!("{:.1}% of the surface ({n} faces)", 100.0 * p));
    }
    if let Some(d) = f.mean_distortion {
        line("mean distortion", format!("{d:.4}"));
    }
    if let Some(c) = &f.colour {
        let db = |s: &super::colour::ColourStats| match s.psnr_db {
            Some(x) if x.is_finite() => format!("{x:.1} dB ({} points)", s.samples),
            Some(_) => format!("identical ({} points)", s.samples),
            None => "no point".into(),
        };
        line("colour PSNR, all", db(&c.all));
        line("colour PSNR, copied faces", db(&c.preserved));
        line("colour PSNR, resampled faces", db(&c.resampled));
        line("colour PSNR, faces with no input UV area", db(&c.zero_uv_area));
    }
    if let Some(l) = f.faces_lost {
        line("faces that lost their texture", l.to_string());
    }
    *h += "</table>\n";
}
