//! SVG plots with logarithmic axes (convergence ladders, time–error trade-offs), drawn with
//! the `plotters` crate's SVG backend into a string for the HTML reports.

use plotters::prelude::*;

/// One series: a name and its (x, y) points, both > 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points, x and y > 0.
    pub points: Vec<(f64, f64)>,
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
            .build_cartesian_2d(xs.log_scale(), ys.log_scale())
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
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| fail(&e))?;
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
    }

    #[test]
    fn empty_plot_is_still_drawn() {
        let s = loglog("nothing", "x", "y", &[]).unwrap();
        assert!(s.starts_with("<svg") && s.contains("nothing"));
    }
}
