//! Seed 001's Fig. 20 and Fig. 21 from the reproduction's report, side by
//! side in one PNG: every quadlet read and write time by iteration (the
//! bands show), and the mean block read and write time against the block
//! size with the fitted lines and the paper's (dashed).

use std::path::Path;

use plotters::prelude::*;

use firelink_testbed::snake::bench::Seed001Report;

use crate::{FAMILY, PALETTE, PlotError, draw_axes, draw_err, draw_legend, ensure_font};

/// The paper's lines of Fig. 21: base latency, Mb/s.
const PAPER_READ: (f64, f64) = (33.2, 360.0);
const PAPER_WRITE: (f64, f64) = (30.7, 290.0);

/// Draw Fig. 20 and Fig. 21 of seed 001 from `report` into a PNG file.
///
/// # Errors
/// [`PlotError::Empty`] for a report without measurements; no font;
/// drawing or writing failed.
pub fn seed001(report: &Seed001Report, path: &Path) -> Result<(), PlotError> {
    if report.quadlet_read_us.is_empty() || report.block_read.is_empty() {
        return Err(PlotError::Empty("the seed 001 report has no measurements"));
    }
    ensure_font()?;
    let root = BitMapBackend::new(path, (1400, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(path, e))?;
    let (left, right) = root.split_horizontally(640);
    let (read_c, write_c) = (PALETTE[0], PALETTE[1]);

    // Fig. 20.
    let n = report
        .quadlet_read_us
        .len()
        .max(report.quadlet_write_us.len());
    let top = report
        .quadlet_read_us
        .iter()
        .chain(&report.quadlet_write_us)
        .fold(0.0f32, |m, &x| m.max(x));
    let mut chart = ChartBuilder::on(&left)
        .caption("Quadlet transactions (seed 001, Fig. 20)", (FAMILY, 22))
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(0f64..n as f64, 0f64..(f64::from(top) * 1.15).max(60.0))
        .map_err(|e| draw_err(path, e))?;
    draw_axes(&mut chart, ("iteration", "transaction time, us"), 16, path)?;
    for (label, data, colour, paper) in [
        ("read", &report.quadlet_read_us, read_c, 34.5),
        ("write", &report.quadlet_write_us, write_c, 30.2),
    ] {
        chart
            .draw_series(
                data.iter().enumerate().map(|(i, &t)| {
                    Circle::new((i as f64, f64::from(t)), 1, colour.mix(0.35).filled())
                }),
            )
            .map_err(|e| draw_err(path, e))?
            .label(format!("{label} (simulated)"))
            .legend(move |(x, y)| Circle::new((x + 12, y), 4, colour.filled()));
        let mean = data.iter().map(|&t| f64::from(t)).sum::<f64>() / data.len().max(1) as f64;
        chart
            .draw_series(LineSeries::new(
                [(0.0, mean), (n as f64, mean)],
                colour.stroke_width(2),
            ))
            .map_err(|e| draw_err(path, e))?
            .label(format!("{label} mean {mean:.1} us (paper {paper} us)"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(DashedLineSeries::new(
                [(0.0, paper), (n as f64, paper)],
                6,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(|e| draw_err(path, e))?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 13, path)?;

    // Fig. 21.
    let max_q = report
        .block_read
        .iter()
        .chain(&report.block_write)
        .map(|p| p.quadlets)
        .max()
        .unwrap_or(512) as f64;
    let top = report
        .block_read
        .iter()
        .chain(&report.block_write)
        .fold(0.0f64, |m, p| m.max(p.mean_us));
    let mut chart = ChartBuilder::on(&right)
        .caption(
            "Block transactions against size (seed 001, Fig. 21)",
            (FAMILY, 22),
        )
        .margin(14)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(0f64..max_q * 1.02, 0f64..top * 1.15)
        .map_err(|e| draw_err(path, e))?;
    draw_axes(
        &mut chart,
        (
            "block size, quadlets",
            "transaction time, us (mean per size)",
        ),
        16,
        path,
    )?;
    for (label, points, fit, colour, paper) in [
        (
            "read",
            &report.block_read,
            report.block_read_fit,
            read_c,
            PAPER_READ,
        ),
        (
            "write",
            &report.block_write,
            report.block_write_fit,
            write_c,
            PAPER_WRITE,
        ),
    ] {
        chart
            .draw_series(
                points.iter().map(|p| {
                    Circle::new((p.quadlets as f64, p.mean_us), 2, colour.mix(0.5).filled())
                }),
            )
            .map_err(|e| draw_err(path, e))?
            .label(format!("{label} (simulated)"))
            .legend(move |(x, y)| Circle::new((x + 12, y), 4, colour.filled()));
        let line = |base: f64, mbps: f64| [(0.0, base), (max_q, base + max_q * 32.0 / mbps)];
        chart
            .draw_series(LineSeries::new(
                line(fit.base_us, fit.mbps),
                colour.stroke_width(2),
            ))
            .map_err(|e| draw_err(path, e))?
            .label(format!(
                "{label} fit: {:.1} us + {:.0} Mb/s",
                fit.base_us, fit.mbps
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(DashedLineSeries::new(
                line(paper.0, paper.1),
                6,
                4,
                BLACK.stroke_width(1),
            ))
            .map_err(|e| draw_err(path, e))?
            .label(format!("{label}, paper: {} us + {} Mb/s", paper.0, paper.1))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(1)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 13, path)?;
    root.present().map_err(|e| draw_err(path, e))?;
    Ok(())
}
