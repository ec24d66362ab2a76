//! Seed 002's Table III as a figure: read-transaction time against
//! payload under Xenomai and RTLinux, the simulation's median, 99th
//! percentile and maximum beside the seed's worst cases.

use std::path::Path;

use plotters::prelude::*;

use firelink_testbed::mahru::table3::{Table3Point, Table3Report};

use super::{FAMILY, PALETTE, PlotError, draw_axes, draw_err, draw_legend, ensure_font};

/// Draw Table III (simulated distribution and the seed's WCET) into a PNG.
///
/// # Errors
/// [`PlotError::Empty`] without points; no font; drawing or writing
/// failed.
pub fn table3(report: &Table3Report, path: &Path) -> Result<(), PlotError> {
    if report.points.is_empty() {
        return Err(PlotError::Empty("the Table III report has no points"));
    }
    ensure_font()?;
    let max_payload = report.points.iter().map(|p| p.payload).max().unwrap_or(496) as f64;
    let max_time = report
        .points
        .iter()
        .map(|p| p.total.max.max(p.paper_wcet_us.unwrap_or(0.0)))
        .fold(0.0f64, f64::max);
    let root = BitMapBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Read transaction time by payload (seed 002, Table III; {} simulated reads per point)",
                report.reads
            ),
            (FAMILY, 22),
        )
        .margin(16)
        .x_label_area_size(52)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..max_payload * 1.05, 0.0..max_time * 1.1)
        .map_err(|e| draw_err(path, e))?;
    draw_axes(
        &mut chart,
        ("payload, bytes", "call to return, us"),
        17,
        path,
    )?;
    let mut systems: Vec<&str> = Vec::new();
    for p in &report.points {
        if !systems.contains(&p.rtos) {
            systems.push(p.rtos);
        }
    }
    for (i, rtos) in systems.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let mut points: Vec<&Table3Point> =
            report.points.iter().filter(|p| p.rtos == *rtos).collect();
        points.sort_by_key(|p| p.payload);
        let line = |f: fn(&Table3Point) -> f64| -> Vec<(f64, f64)> {
            points.iter().map(|p| (p.payload as f64, f(p))).collect()
        };
        chart
            .draw_series(LineSeries::new(
                line(|p| p.total.max),
                colour.stroke_width(3),
            ))
            .map_err(|e| draw_err(path, e))?
            .label(format!("{rtos}: simulated maximum"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(3))
            });
        chart
            .draw_series(
                line(|p| p.total.p99)
                    .into_iter()
                    .map(|xy| Circle::new(xy, 4, colour.filled())),
            )
            .map_err(|e| draw_err(path, e))?
            .label(format!("{rtos}: simulated 99th percentile"))
            .legend(move |(x, y)| Circle::new((x + 12, y), 4, colour.filled()));
        chart
            .draw_series(LineSeries::new(
                line(|p| p.total.p50),
                colour.stroke_width(1),
            ))
            .map_err(|e| draw_err(path, e))?
            .label(format!("{rtos}: simulated median"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(1))
            });
        let paper: Vec<(f64, f64)> = points
            .iter()
            .filter_map(|p| p.paper_wcet_us.map(|w| (p.payload as f64, w)))
            .collect();
        chart
            .draw_series(
                paper
                    .into_iter()
                    .map(|xy| Cross::new(xy, 8, colour.stroke_width(2))),
            )
            .map_err(|e| draw_err(path, e))?
            .label(format!("{rtos}: the seed's WCET"))
            .legend(move |(x, y)| Cross::new((x + 12, y), 6, colour.stroke_width(2)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 15, path)?;
    root.present().map_err(|e| draw_err(path, e))?;
    Ok(())
}
