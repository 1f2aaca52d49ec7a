//! The report's plots as SVG, drawn by `plotters` with its SVG backend (no fonts or system
//! libraries: the browser renders the text): grouped bar charts over named bins, optionally on a
//! logarithmic count axis.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::ReportError;

/// One series of a bar chart: a name for the legend and one value and colour per bin.
pub struct Series {
    pub name: String,
    pub bars: Vec<(f64, [u8; 3])>,
}

/// A bar chart: bins along x (named by `bins`), one bar per series in each bin.
pub struct BarChart<'a> {
    pub title: &'a str,
    pub x_desc: &'a str,
    pub y_desc: &'a str,
    pub bins: Vec<String>,
    pub series: Vec<Series>,
    /// A logarithmic y axis (counts spanning decades); empty bins then draw nothing.
    pub log_y: bool,
}

const SIZE: (u32, u32) = (720, 360);

fn plot_error(e: impl std::fmt::Display) -> ReportError {
    ReportError::Plot(e.to_string())
}

impl BarChart<'_> {
    /// The chart as an SVG document.
    pub fn to_svg(&self) -> Result<String, ReportError> {
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
            root.fill(&WHITE).map_err(plot_error)?;
            self.draw(&root)?;
            root.present().map_err(plot_error)?;
        }
        Ok(svg)
    }

    fn y_max(&self) -> f64 {
        let m = self.series.iter().flat_map(|s| s.bars.iter().map(|b| b.0)).fold(0.0, f64::max);
        if self.log_y { (m * 2.0).max(10.0) } else { (m * 1.1).max(1e-9) }
    }

    fn draw(
        &self,
        root: &DrawingArea<SVGBackend, plotters::coord::Shift>,
    ) -> Result<(), ReportError> {
        let n = self.bins.len().max(1);
        let bins = &self.bins;
        let label = |x: &f64| {
            let k = (x - 0.5).round();
            if (x - 0.5 - k).abs() < 1e-6 && k >= 0.0 {
                bins.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        let mut builder = ChartBuilder::on(root);
        builder
            .caption(self.title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(64);
        if self.log_y {
            let mut chart = builder
                .build_cartesian_2d(0f64..n as f64, (0.5f64..self.y_max()).log_scale())
                .map_err(plot_error)?;
            chart
                .configure_mesh()
                .x_labels(n * 2 + 1)
                .x_label_formatter(&label)
                .x_desc(self.x_desc)
                .y_desc(self.y_desc)
                .disable_x_mesh()
                .draw()
                .map_err(plot_error)?;
            self.bars(&mut chart, 0.5)
        } else {
            let mut chart = builder
                .build_cartesian_2d(0f64..n as f64, 0f64..self.y_max())
                .map_err(plot_error)?;
            chart
                .configure_mesh()
                .x_labels(n * 2 + 1)
                .x_label_formatter(&label)
                .x_desc(self.x_desc)
                .y_desc(self.y_desc)
                .disable_x_mesh()
                .draw()
                .map_err(plot_error)?;
            self.bars(&mut chart, 0.0)
        }
    }

    /// Draws the bars (from `y0` up, none for a value not above it) and the legend.
    fn bars<'a, Y: Ranged<ValueType = f64>>(
        &self,
        chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<RangedCoordf64, Y>>,
        y0: f64,
    ) -> Result<(), ReportError> {
        let width = 0.8 / self.series.len().max(1) as f64;
        for (s, series) in self.series.iter().enumerate() {
            let bars = series.bars.iter().enumerate().filter(|(_, b)| b.0 > y0).map(|(k, b)| {
                let x0 = k as f64 + 0.1 + s as f64 * width;
                Rectangle::new([(x0, y0), (x0 + width, b.0)], rgb(b.1).filled())
            });
            let colour = series.bars.first().map_or([0, 0, 0], |b| b.1);
            chart.draw_series(bars).map_err(plot_error)?.label(series.name.as_str()).legend(
                move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], rgb(colour).filled()),
            );
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .border_style(BLACK)
            .background_style(WHITE.mix(0.85))
            .draw()
            .map_err(plot_error)
    }
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// Bins of chart sizes: `[2^k, 2^(k+1))` faces, `k` from 0 to the largest chart's.
pub fn size_bins(sizes: &[u32]) -> Vec<u64> {
    let mut bins = Vec::new();
    for &s in sizes {
        let k = (31 - s.max(1).leading_zeros()) as usize;
        if bins.len() <= k {
            bins.resize(k + 1, 0);
        }
        bins[k] += 1;
    }
    bins
}

/// The name of size bin `k`: its range of faces per chart.
pub fn size_bin_name(k: usize) -> String {
    let short = |n: u64| if n >= 1024 { format!("{}k", n / 1024) } else { n.to_string() };
    match k {
        0 => "1".into(),
        1 => "2-3".into(),
        k if k >= 10 => format!("{}-{}", short(1 << k), short(1 << (k + 1))),
        _ => format!("{}-{}", 1u64 << k, (1u64 << (k + 1)) - 1),
    }
}

/// Distortion bins: exact copies, then `(0, 1e-4)`, half decades up to 1, and `≥ 1`; each bin's
/// upper bound (for a representative colour) and name.
pub fn energy_bins() -> Vec<(f64, String)> {
    let mut bins = vec![(0.0, "0".to_string()), (1e-4, "<1e-4".to_string())];
    for k in 0..8 {
        let hi = 10f64.powf(-4.0 + 0.5 * f64::from(k + 1));
        bins.push((hi, format!("<{}", fmt_power(hi))));
    }
    bins.push((f64::INFINITY, "≥1".to_string()));
    bins
}

fn fmt_power(x: f64) -> String {
    let e = x.log10();
    if (e - e.round()).abs() < 1e-9 { format!("1e{}", e.round()) } else { format!("{x:.0e}") }
}

/// The bin of [`energy_bins`] an energy falls in.
pub fn energy_bin(e: f64, bins: &[(f64, String)]) -> usize {
    if e <= 0.0 {
        return 0;
    }
    bins.iter().position(|b| e < b.0).unwrap_or(bins.len() - 1).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_bins_are_powers_of_two() {
        assert_eq!(size_bins(&[1, 2, 3, 4, 7, 8, 100]), vec![1, 2, 2, 1, 0, 0, 1]);
        assert_eq!(size_bin_name(3), "8-15");
    }

    #[test]
    fn energies_fall_in_increasing_bins() {
        let bins = energy_bins();
        assert_eq!(energy_bin(0.0, &bins), 0);
        assert_eq!(energy_bin(1e-6, &bins), 1);
        assert!(energy_bin(0.01, &bins) < energy_bin(0.5, &bins));
        assert_eq!(energy_bin(5.0, &bins), bins.len() - 1);
    }

    #[test]
    fn a_bar_chart_renders_as_svg_with_its_labels() {
        let chart = BarChart {
            title: "Chart sizes",
            x_desc: "faces per chart",
            y_desc: "charts",
            bins: (0..4).map(size_bin_name).collect(),
            series: vec![
                Series { name: "before".into(), bars: vec![(100.0, [0, 0, 255]); 4] },
                Series { name: "after".into(), bars: vec![(3.0, [255, 0, 0]); 4] },
            ],
            log_y: true,
        };
        let svg = chart.to_svg().expect("renders");
        assert!(svg.starts_with("<svg") && svg.contains("Chart sizes") && svg.contains("8-15"));
        assert!(svg.matches("<rect").count() >= 8, "bars drawn");
    }
}
