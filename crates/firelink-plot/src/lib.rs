//! # firelink-plot: the benchmarks' figures as PNG files
//!
//! Drawn with [`plotters`] (bitmap backend, text through `ab_glyph` from a
//! TrueType font found on the system). [`fig11`] draws seed 000's Fig. 11
//! from a [`BenchReport`]: I/O time per cycle against the number of boards,
//! one series per transport and protocol, measured points filled, points
//! from the cost model hollow (and named so in the legend), the paper's
//! 8-board figures as crosses. Both axes are logarithmic so that the
//! paper's range (2 to 8 boards) stays readable next to 62 boards.
//! [`mahru::table3`] draws seed 002's Table III (read time by payload)
//! from the simulation beside the seed's worst cases.
//!
//! [`seed001()`] draws seed 001's Fig. 20 and Fig. 21 from the
//! reproduction of its bus measurements
//! ([`firelink_testbed::snake::bench`]).
//!
//! The font: `FIRELINK_FONT` if set, else the first of a few usual paths of
//! DejaVu Sans, Liberation Sans or FreeSans (`apt-get install
//! fonts-dejavu-core` provides one).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;

use firelink_testbed::dvrk::bench::{BenchPoint, BenchReport};

mod seed001;
pub use seed001::seed001;

pub mod mahru;

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// No usable TrueType font.
    #[error(
        "no TrueType font found for the plot's text (set FIRELINK_FONT, or install fonts-dejavu-core); tried {tried}"
    )]
    NoFont {
        /// The paths tried.
        tried: String,
    },
    /// Nothing to draw.
    #[error("nothing to plot: {0}")]
    Empty(&'static str),
    /// Drawing or writing the file failed.
    #[error("drawing {path}: {message}")]
    Draw {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

/// The font family name the figures use.
const FAMILY: &str = "sans-serif";

/// Usual places of a sans-serif TrueType font.
const FONT_PATHS: [&str; 6] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
];

/// Find and register the font once for the whole process.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let mut candidates: Vec<PathBuf> = Vec::new();
            if let Some(p) = std::env::var_os("FIRELINK_FONT") {
                candidates.push(PathBuf::from(p));
            }
            candidates.extend(FONT_PATHS.iter().map(PathBuf::from));
            for path in &candidates {
                let Ok(bytes) = std::fs::read(path) else {
                    continue;
                };
                // Registered fonts live for the whole process.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(FAMILY, FontStyle::Normal, bytes).is_ok() {
                    return Ok(());
                }
            }
            Err(candidates
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "))
        })
        .clone()
        .map_err(|tried| PlotError::NoFont { tried })
}

/// Series colours, one per (transport, protocol).
const PALETTE: [RGBColor; 6] = [
    RGBColor(200, 30, 30),
    RGBColor(30, 60, 200),
    RGBColor(230, 130, 20),
    RGBColor(20, 150, 60),
    RGBColor(150, 40, 170),
    RGBColor(90, 90, 90),
];

/// One series of the figure: a transport (with the UDP wait mode) and a
/// protocol.
struct Series<'a> {
    label: String,
    points: Vec<&'a BenchPoint>,
}

fn series(report: &BenchReport) -> Vec<Series<'_>> {
    let mut out: Vec<Series<'_>> = Vec::new();
    for p in &report.results {
        // UDP points say how the host waited (each mode is a series);
        // the `eth` transport's board sets are series of their own.
        let mut label = match p.wait {
            Some(wait) => format!("{} ({wait}) {}", p.transport, p.protocol_asked),
            None => format!("{} {}", p.transport, p.protocol_asked),
        };
        if let Some(set) = p.board_set {
            label = format!("{label}, {set}");
        }
        match out.iter_mut().find(|s| s.label == label) {
            Some(s) => s.points.push(p),
            None => out.push(Series {
                label,
                points: vec![p],
            }),
        }
    }
    for s in &mut out {
        s.points.sort_by_key(|p| p.boards);
    }
    out
}

fn draw_err(path: &Path, e: impl std::fmt::Display) -> PlotError {
    PlotError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Draw a chart's axes in the figures' style: whole-number labels,
/// `x_desc` and `y_desc` at font size `size` (labels one smaller), no
/// light grid lines.
fn draw_axes<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    (x_desc, y_desc): (&str, &str),
    size: u32,
    path: &Path,
) -> Result<(), PlotError>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0}"))
        .light_line_style(WHITE)
        .label_style((FAMILY, size - 2))
        .axis_desc_style((FAMILY, size))
        .draw()
        .map_err(|e| draw_err(path, e))
}

/// Draw a chart's legend in the figures' style at `position`, labels at
/// font size `size`.
fn draw_legend<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    position: SeriesLabelPosition,
    size: u32,
    path: &Path,
) -> Result<(), PlotError>
where
    DB: DrawingBackend + 'a,
    X: Ranged,
    Y: Ranged,
{
    chart
        .configure_series_labels()
        .position(position)
        .label_font((FAMILY, size))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(|e| draw_err(path, e))
}

/// Round I/O-time grid values (1-2-5 steps) inside `range`.
fn time_ticks(range: &std::ops::Range<f64>) -> Vec<f64> {
    let mut out = Vec::new();
    let mut decade = 1.0;
    while decade <= range.end {
        for m in [1.0, 2.0, 5.0] {
            let v = decade * m;
            if v >= range.start && v <= range.end {
                out.push(v);
            }
        }
        decade *= 10.0;
    }
    out
}

/// Draw seed 000's Fig. 11 from a benchmark report into a PNG file.
pub fn fig11(report: &BenchReport, path: &Path) -> Result<(), PlotError> {
    if report.results.is_empty() {
        return Err(PlotError::Empty("the benchmark report has no points"));
    }
    ensure_font()?;
    let max_boards = report.results.iter().map(|p| p.boards).max().unwrap_or(8);
    let times = report
        .results
        .iter()
        .map(|p| p.io_time_us.median)
        .chain([report.paper.sequential_8_us, report.paper.broadcast_8_us]);
    let (lo, hi) = times.fold((f64::INFINITY, 0.0f64), |(l, h), t| (l.min(t), h.max(t)));
    let y_range = (lo.max(1.0) / 1.5)..(hi * 1.8);
    let x_range = 1.0f64..(max_boards.max(8) as f64 * 1.25);

    let board_ticks: Vec<f64> = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 62.0]
        .into_iter()
        .filter(|&n| n <= x_range.end)
        .collect();
    let root = BitMapBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "I/O time per servo cycle against boards (seed 000, Fig. 11)",
            (FAMILY, 24),
        )
        .margin(16)
        .x_label_area_size(52)
        .y_label_area_size(76)
        .build_cartesian_2d(
            x_range.log_scale().with_key_points(board_ticks.to_vec()),
            y_range
                .clone()
                .log_scale()
                .with_key_points(time_ticks(&y_range)),
        )
        .map_err(|e| draw_err(path, e))?;
    draw_axes(
        &mut chart,
        (
            "boards on the bus (log scale)",
            "I/O time per cycle, us (log scale)",
        ),
        17,
        path,
    )?;
    for (i, s) in series(report).iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let line: Vec<(f64, f64)> = s
            .points
            .iter()
            .map(|p| (p.boards as f64, p.io_time_us.median))
            .collect();
        chart
            .draw_series(LineSeries::new(line, colour.stroke_width(2)))
            .map_err(|e| draw_err(path, e))?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(
                s.points
                    .iter()
                    .filter(|p| !p.model && p.protocol == p.protocol_asked)
                    .map(|p| {
                        Circle::new((p.boards as f64, p.io_time_us.median), 5, colour.filled())
                    }),
            )
            .map_err(|e| draw_err(path, e))?;
        let fell_back: Vec<&&BenchPoint> = s
            .points
            .iter()
            .filter(|p| !p.model && p.protocol != p.protocol_asked)
            .collect();
        if let Some(first) = fell_back.first() {
            chart
                .draw_series(fell_back.iter().map(|p| {
                    TriangleMarker::new((p.boards as f64, p.io_time_us.median), 7, colour.filled())
                }))
                .map_err(|e| draw_err(path, e))?
                .label(format!(
                    "{}: ran {} (scan refused it)",
                    s.label, first.protocol
                ))
                .legend(move |(x, y)| TriangleMarker::new((x + 12, y), 6, colour.filled()));
        }
        let modelled: Vec<&&BenchPoint> = s.points.iter().filter(|p| p.model).collect();
        if !modelled.is_empty() {
            chart
                .draw_series(modelled.iter().map(|p| {
                    Circle::new(
                        (p.boards as f64, p.io_time_us.median),
                        6,
                        colour.stroke_width(2),
                    )
                }))
                .map_err(|e| draw_err(path, e))?
                .label(format!("{} (model, > 16 boards)", s.label))
                .legend(move |(x, y)| Circle::new((x + 12, y), 5, colour.stroke_width(2)));
        }
    }
    let paper = [
        (8.0, report.paper.sequential_8_us),
        (8.0, report.paper.broadcast_8_us),
    ];
    chart
        .draw_series(
            paper
                .iter()
                .map(|&(x, y)| Cross::new((x, y), 8, BLACK.stroke_width(2))),
        )
        .map_err(|e| draw_err(path, e))?
        .label("paper, 8 boards (seed 000)")
        .legend(|(x, y)| Cross::new((x + 12, y), 6, BLACK.stroke_width(2)));
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, 15, path)?;
    root.present().map_err(|e| draw_err(path, e))?;
    Ok(())
}
