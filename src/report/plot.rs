//! SVG plots for the HTML reports, drawn with the `plotters` crate's SVG backend into a
//! string: log-log lines (convergence ladders, time–error trade-offs) and a dot plot of each
//! check's deviation from its expected value in standard errors, per renderer.

use plotters::prelude::*;

/// One series: a name and its (x, y) points, both > 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points, x and y > 0.
    pub points: Vec<(f64, f64)>,
    /// A dashed guide of this slope (in log-log) through the first point, in the series'
    /// colour: the rate theory predicts, beside the measured one.
    pub guide_slope: Option<f64>,
}

/// Why a plot could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("cannot draw the plot \"{title}\": {message}")]
pub struct PlotError {
    /// The plot's title.
    pub title: String,
    /// What the drawing backend reported.
    pub message: String,
}

/// Plot width and height, px.
const SIZE: (u32, u32) = (720, 380);

/// Width of the legend column at the right, px.
const LEGEND: u32 = 190;

/// Matplotlib's "tab10" palette.
const COLOURS: [RGBColor; 10] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x17, 0xbe, 0xcf),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0xbc, 0xbd, 0x22),
];

/// The whole decades enclosing the positive values of `v` (1 to 10 when there are none).
fn decades(v: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| *x > 0.0 && x.is_finite()) {
        lo = lo.min(x.log10());
        hi = hi.max(x.log10());
    }
    if lo > hi {
        return 1.0..10.0;
    }
    let (lo, hi) = (lo.floor(), hi.ceil().max(lo.floor() + 1.0));
    10f64.powf(lo)..10f64.powf(hi)
}

/// A log-log plot of `series` (lines through the points, the points marked, a legend in a
/// column at the right) as an SVG element; points with a coordinate <= 0 are left out.
pub fn loglog(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> Result<String, PlotError> {
    let fail = |e: &dyn std::fmt::Display| PlotError {
        title: title.to_string(),
        message: e.to_string(),
    };
    let kept: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            let ok = |v: f64| v > 0.0 && v.is_finite();
            s.points
                .iter()
                .copied()
                .filter(|&(x, y)| ok(x) && ok(y))
                .collect()
        })
        .collect();
    let xs = decades(kept.iter().flatten().map(|p| p.0));
    let ys = decades(kept.iter().flatten().map(|p| p.1));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let (plot, legend) = root.split_horizontally(SIZE.0 - LEGEND);
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(xs.log_scale(), ys.clone().log_scale())
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()
            .map_err(|e| fail(&e))?;
        for (i, (s, points)) in series.iter().zip(&kept).enumerate() {
            let c = COLOURS[i % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(points.iter().copied(), c.stroke_width(2)))
                .map_err(|e| fail(&e))?;
            // past ten series the colours repeat, so the marker changes with each round
            let marker = Marker::of(i / COLOURS.len());
            chart
                .draw_series(points.iter().map(|&p| marker.at(p, c)))
                .map_err(|e| fail(&e))?;
            if let (Some(k), Some(&(x0, y0)), Some(&(x1, _))) =
                (s.guide_slope, points.first(), points.last())
            {
                // y = y0·(x/x0)^k, clipped to the plot's y range
                let guide = [x0, x1].map(|x| (x, y0 * (x / x0).powf(k)));
                let inside = guide
                    .iter()
                    .all(|&(_, y)| y >= ys.start && y <= ys.end && y.is_finite());
                if inside {
                    chart
                        .draw_series(DashedLineSeries::new(guide, 6, 4, c.stroke_width(1)))
                        .map_err(|e| fail(&e))?;
                }
            }
            let y = 40 + 18 * i as i32;
            legend
                .draw(&PathElement::new(vec![(4, y), (24, y)], c.stroke_width(2)))
                .map_err(|e| fail(&e))?;
            legend
                .draw(&Text::new(
                    s.name.as_str(),
                    (30, y - 7),
                    ("sans-serif", 13).into_font(),
                ))
                .map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    Ok(svg)
}

/// Point markers, one per round of the colour palette.
#[derive(Debug, Clone, Copy)]
enum Marker {
    Circle,
    Triangle,
    Cross,
}

impl Marker {
    fn of(round: usize) -> Self {
        [Marker::Circle, Marker::Triangle, Marker::Cross][round % 3]
    }

    fn at<DB: DrawingBackend, C: Into<ShapeStyle>>(
        self,
        p: (f64, f64),
        c: C,
    ) -> DynElement<'static, DB, (f64, f64)> {
        match self {
            Marker::Circle => Circle::new(p, 3, c).into_dyn(),
            Marker::Triangle => TriangleMarker::new(p, 4, c).into_dyn(),
            Marker::Cross => Cross::new(p, 4, c).into_dyn(),
        }
    }
}

/// Deviations drawn beyond this many standard errors are clipped to the edge (as ×).
pub const DEVIATION_CLIP: f64 = 10.0;

/// One renderer's deviations (estimate − expected)/se, one per check (None: not measured,
/// or no standard error to divide by).
#[derive(Debug, Clone, PartialEq)]
pub struct Deviations {
    /// Legend text (the renderer).
    pub name: String,
    /// Per check, in the order of the plot's check names.
    pub sigmas: Vec<Option<f64>>,
}

/// A dot plot, one row per check (names at the left), of each renderer's deviation from the
/// expected value in standard errors, with the two-sided test's bounds ±`bound` dashed;
/// deviations beyond ±[`DEVIATION_CLIP`] are drawn at the edge as crosses.
pub fn deviation_dots(
    title: &str,
    checks: &[String],
    renderers: &[Deviations],
    bound: f64,
) -> Result<String, PlotError> {
    let fail = |e: &dyn std::fmt::Display| PlotError {
        title: title.to_string(),
        message: e.to_string(),
    };
    let rows = checks.len().max(1);
    let label_width = checks
        .iter()
        .map(|c| c.chars().count())
        .max()
        .unwrap_or(8)
        .clamp(8, 60) as u32
        * 7;
    let size = (label_width + 520 + LEGEND, 110 + 16 * rows as u32);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let (plot, legend) = root.split_horizontally(size.0 - LEGEND);
        let c = DEVIATION_CLIP;
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, ("sans-serif", 16))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(label_width)
            .build_cartesian_2d(-c - 0.5..c + 0.5, -0.5..rows as f64 - 0.5)
            .map_err(|e| fail(&e))?;
        let name_of = |y: &f64| -> String {
            let i = y.round();
            if (y - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < checks.len() {
                checks[checks.len() - 1 - i as usize].clone()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_desc("(estimate − expected) / standard error")
            .y_labels(rows)
            .y_label_formatter(&name_of)
            .x_labels(11)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(|e| fail(&e))?;
        let grey = RGBColor(0x80, 0x80, 0x80);
        for x in [-bound, bound] {
            let top = rows as f64 - 0.5;
            chart
                .draw_series(DashedLineSeries::new(
                    [(x, -0.5), (x, top)],
                    5,
                    4,
                    grey.stroke_width(1),
                ))
                .map_err(|e| fail(&e))?;
        }
        for (k, r) in renderers.iter().enumerate() {
            let colour = COLOURS[k % COLOURS.len()];
            // renderers side by side within a row, so equal values do not hide each other
            let dy = (k as f64 - (renderers.len() as f64 - 1.0) / 2.0) * 0.18;
            let points = r.sigmas.iter().enumerate().filter_map(|(i, s)| {
                let y = (checks.len() - 1 - i) as f64 + dy;
                s.filter(|s| s.is_finite()).map(|s| (s, y))
            });
            chart
                .draw_series(points.map(|(s, y)| {
                    if s.abs() > c {
                        Cross::new((s.signum() * c, y), 4, colour.stroke_width(2)).into_dyn()
                    } else {
                        Circle::new((s, y), 3, colour.filled()).into_dyn()
                    }
                }))
                .map_err(|e| fail(&e))?;
            let y = 40 + 18 * k as i32;
            legend
                .draw(&Circle::new((14, y), 4, colour.filled()))
                .map_err(|e| fail(&e))?;
            legend
                .draw(&Text::new(
                    r.name.as_str(),
                    (30, y - 7),
                    ("sans-serif", 13).into_font(),
                ))
                .map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plot_has_axes_series_and_legend() {
        let s = loglog(
            "t",
            "samples",
            "RMSE",
            &[Series {
                name: "a<b".into(),
                points: vec![(1.0, 1.0), (100.0, 0.1), (0.0, 1.0)],
                guide_slope: Some(-0.5),
            }],
        )
        .unwrap();
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        assert_eq!(
            s.matches("<circle").count(),
            2,
            "non-positive points are left out"
        );
        // the legend text is escaped; the axes carry decade labels and their names
        assert!(s.contains("a&lt;b"), "{s}");
        assert!(s.contains("1e0") && s.contains("1e2") && s.contains("samples"));
        assert!(s.contains("<polyline"));
        // the guide through the first point is dashed
        assert!(
            s.contains("stroke-dasharray")
                || s.matches("<polyline").count() > 1
                || s.matches("<line").count() > 0,
            "{s}"
        );
    }

    #[test]
    fn deviation_dots_mark_rows_bounds_and_clipped_values() {
        let checks = ["a".to_string(), "b<c".to_string(), "d".to_string()];
        let s = deviation_dots(
            "deviations",
            &checks,
            &[
                Deviations {
                    name: "furnace".into(),
                    sigmas: vec![Some(0.5), Some(-1.0), None],
                },
                Deviations {
                    name: "other".into(),
                    sigmas: vec![Some(-400.0), Some(2.0), Some(f64::NAN)],
                },
            ],
            3.9,
        )
        .unwrap();
        assert!(s.starts_with("<svg") && s.trim_end().ends_with("</svg>"));
        // every check's name labels its row; text is escaped
        assert!(
            s.contains("\na\n") && s.contains("\nb&lt;c\n") && s.contains("\nd\n"),
            "{s}"
        );
        // three finite deviations inside the clip as dots (plus two legend dots)
        assert_eq!(s.matches("<circle").count(), 3 + 2, "{s}");
        assert!(s.contains("furnace") && s.contains("other"));
    }

    #[test]
    fn empty_plot_is_still_drawn() {
        let s = loglog("nothing", "x", "y", &[]).unwrap();
        assert!(s.starts_with("<svg") && s.contains("nothing"));
    }
}
