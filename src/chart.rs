//! Speed-versus-accuracy charts: bake time against error on log-log axes, one line per
//! sampling strategy and backend, each point labelled with its sample count.
//!
//! Text is drawn with Bitstream Vera Sans compiled into the binary (`assets/fonts/`), because
//! the machines that make these charts (CI, containers) often have no fonts installed, and
//! plotters' default font lookup would then fail at the first axis label. The SVG output names
//! the family `sans-serif` and leaves the glyphs to the viewer; only its layout uses Vera's
//! metrics.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{Error, Result};
use crate::fs::{format_by_extension, write_atomically};

/// One bake: how long it took, how far its result is from the reference, and how many samples
/// per vertex it used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartPoint {
    pub seconds: f64,
    pub error: f64,
    pub samples: u32,
}

/// One line of the chart: the bakes of one strategy on one backend, e.g. "stratified cpu".
#[derive(Debug, Clone, PartialEq)]
pub struct ChartSeries {
    pub label: String,
    pub points: Vec<ChartPoint>,
}

/// One plot of the chart, with its own title, error axis and legend.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartPanel {
    pub title: String,
    pub y_label: String,
    pub series: Vec<ChartSeries>,
}

/// Draws the panels side by side (log-log: x = bake time in seconds, y = error), one line per
/// series with markers, each point labelled with its sample count, a legend, a title.
///
/// The format follows the extension: `.svg` or `.png`; anything else is an `Error::Options`.
/// Points whose time or error is not positive and finite cannot sit on a log axis and are left
/// out; a panel left with no point at all is an error. The file is written atomically, so a
/// failed draw leaves nothing behind.
pub fn draw_chart(path: &Path, title: &str, x_label: &str, panels: &[ChartPanel]) -> Result<()> {
    let format = ChartFormat::of(path)?;
    if panels.is_empty() {
        return Err(Error::chart(path, "no panels to draw"));
    }
    let layouts = panels
        .iter()
        .map(|panel| {
            PanelLayout::of(panel).ok_or_else(|| {
                Error::chart(
                    path,
                    format!(
                        "panel \"{}\" has no point with a positive, finite time and error \
                         to draw on log axes",
                        panel.title
                    ),
                )
            })
        })
        .collect::<Result<Vec<_>>>()?;
    register_embedded_font().map_err(|message| Error::chart(path, message))?;
    let chart = Chart {
        title,
        x_label,
        panels,
        layouts: &layouts,
        styles: series_styles(panels),
    };
    let size = chart_size(panels.len());
    let bytes = match format {
        ChartFormat::Svg => render_svg(&chart, size),
        ChartFormat::Png => render_png(&chart, size),
    }
    .map_err(|message| Error::chart(path, format!("cannot draw the chart: {message}")))?;
    write_atomically(path, &bytes)
}

#[derive(Clone, Copy)]
enum ChartFormat {
    Svg,
    Png,
}

impl ChartFormat {
    fn of(path: &Path) -> Result<ChartFormat> {
        format_by_extension(
            path,
            &[("svg", ChartFormat::Svg), ("png", ChartFormat::Png)],
            "charts",
        )
    }
}

/// Checks that `path` names a chart format, before the sweep that the chart shows.
pub fn check_chart_path(path: &Path) -> Result<()> {
    ChartFormat::of(path).map(|_| ())
}

// ---------------------------------------------------------------------------------------------
// Font

/// Vera Sans 1.10, unmodified: 66 KB against DejaVu Sans's 760 KB, and Latin-1 is all the
/// labels need. Licence and provenance in `assets/fonts/`.
static VERA_SANS: &[u8] = include_bytes!("../assets/fonts/Vera.ttf");

/// Registers the embedded font as plotters' `sans-serif`, the family every text style here
/// (and plotters' own defaults) asks for. Done once per process; the outcome is remembered so
/// a bad font reports the same error every time instead of a panic.
fn register_embedded_font() -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font("sans-serif", FontStyle::Normal, VERA_SANS)
                .map_err(|_| "the embedded font Vera.ttf cannot be parsed".to_string())
        })
        .clone()
}

// ---------------------------------------------------------------------------------------------
// Layout: sizes, axis ranges, ticks

/// Each panel gets this many pixels of width; two panels make a 1400 x 600 chart.
const PANEL_WIDTH: u32 = 700;
const CHART_HEIGHT: u32 = 600;

/// Space kept around the data, as fractions of its span in decades. More on the right for the
/// sample-count labels drawn right of each point, more at the top for the legend: errors fall
/// as time grows, so the top right of a panel is where the data is not.
const X_PAD: (f64, f64) = (0.06, 0.14);
const Y_PAD: (f64, f64) = (0.08, 0.35);

/// A narrower axis than half a decade would show at most one tick label.
const MIN_DECADES: f64 = 0.5;

/// More labelled ticks than this crowd a 700-pixel-wide panel.
const MAX_TICKS: usize = 8;

fn chart_size(panels: usize) -> (u32, u32) {
    (PANEL_WIDTH * panels as u32, CHART_HEIGHT)
}

/// A point can sit on log-log axes only if both coordinates are positive and finite.
fn is_drawable(point: &ChartPoint) -> bool {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    positive(point.seconds) && positive(point.error)
}

/// The points of a series that can be drawn, in order of sample count, so the line runs from
/// the cheapest bake to the most expensive one whatever order the caller measured them in.
fn drawable_points(series: &ChartSeries) -> Vec<ChartPoint> {
    let mut points: Vec<ChartPoint> = series.points.iter().copied().filter(is_drawable).collect();
    points.sort_by(|a, b| {
        a.samples
            .cmp(&b.samples)
            .then(a.seconds.total_cmp(&b.seconds))
    });
    points
}

/// Axis ranges and ticks of one panel.
struct PanelLayout {
    x: Range<f64>,
    y: Range<f64>,
    x_ticks: Vec<f64>,
    y_ticks: Vec<f64>,
}

impl PanelLayout {
    /// None when the panel has no drawable point.
    fn of(panel: &ChartPanel) -> Option<PanelLayout> {
        let points: Vec<ChartPoint> = panel.series.iter().flat_map(drawable_points).collect();
        let x = padded_log_range(points.iter().map(|p| p.seconds), X_PAD)?;
        let y = padded_log_range(points.iter().map(|p| p.error), Y_PAD)?;
        Some(PanelLayout {
            x_ticks: log_ticks(&x, MAX_TICKS),
            y_ticks: log_ticks(&y, MAX_TICKS),
            x,
            y,
        })
    }
}

/// The range of positive values `values`, widened to at least `MIN_DECADES` and padded by
/// `pad` (fractions of the span, low side and high side), all measured in decades. None if
/// there are no values.
fn padded_log_range(values: impl Iterator<Item = f64>, pad: (f64, f64)) -> Option<Range<f64>> {
    let (lo, hi) = values.fold(None, |acc: Option<(f64, f64)>, v| {
        let l = v.log10();
        Some(acc.map_or((l, l), |(lo, hi)| (lo.min(l), hi.max(l))))
    })?;
    let widen = (MIN_DECADES - (hi - lo)).max(0.0) / 2.0;
    let (lo, hi) = (lo - widen, hi + widen);
    let span = hi - lo;
    let start = (lo - pad.0 * span).max(-f64::from(MAX_DECADE));
    let end = (hi + pad.1 * span).min(f64::from(MAX_DECADE));
    Some(10f64.powf(start)..10f64.powf(end))
}

/// Axes stay within 10^±307, whole decades inside what a normal f64 holds: padding an extreme
/// value must not reach infinity, which would leave the tick search no decade to stop at.
const MAX_DECADE: i32 = 307;

/// `m × 10^e`, computed so that negative decades divide by an exact power of ten: `3 / 10` is
/// the double nearest 0.3, where `3 × 0.1` is not, and the label would show it.
fn tick_value(mantissa: u32, exponent: i32) -> f64 {
    let scale = 10f64.powi(exponent.abs());
    if exponent >= 0 {
        f64::from(mantissa) * scale
    } else {
        f64::from(mantissa) / scale
    }
}

/// Every `m × 10^e` inside `range` with `m` in `mantissas` and `e` a multiple of `decade_step`.
fn ticks_with(range: &Range<f64>, mantissas: &[u32], decade_step: i32) -> Vec<f64> {
    let first = (range.start.log10().floor() as i32).max(-MAX_DECADE);
    let last = (range.end.log10().ceil() as i32).min(MAX_DECADE);
    (first..=last)
        .filter(|e| e.rem_euclid(decade_step) == 0)
        .flat_map(|e| mantissas.iter().map(move |&m| tick_value(m, e)))
        .filter(|v| range.start <= *v && *v <= range.end)
        .collect()
}

/// The densest "round" ticks on a log axis that number at most `max_ticks`: every digit of a
/// decade for a narrow range, then 1-2-5, 1-3, each decade, every second, fourth... decade.
fn log_ticks(range: &Range<f64>, max_ticks: usize) -> Vec<f64> {
    const MANTISSAS: [&[u32]; 4] = [&[1, 2, 3, 4, 5, 6, 7, 8, 9], &[1, 2, 5], &[1, 3], &[1]];
    for mantissas in MANTISSAS {
        let ticks = ticks_with(range, mantissas, 1);
        if ticks.len() <= max_ticks {
            return ticks;
        }
    }
    let mut step = 2;
    loop {
        let ticks = ticks_with(range, &[1], step);
        // f64 spans about 630 decades, so the step cannot outgrow that before this holds.
        if ticks.len() <= max_ticks {
            return ticks;
        }
        step *= 2;
    }
}

/// The light grid lines: every digit of every decade, unless there are so many decades that
/// they would turn the panel grey.
fn minor_ticks(range: &Range<f64>) -> Vec<f64> {
    let ticks = ticks_with(range, &[1, 2, 3, 4, 5, 6, 7, 8, 9], 1);
    if ticks.len() <= 60 {
        ticks
    } else {
        Vec::new()
    }
}

/// A tick label as short as the value allows: plain decimals near 1 ("0.02", "300"),
/// scientific notation far from it ("1e-5", "2e6") where decimals would be long.
fn tick_label(value: f64) -> String {
    if (1e-4..1e5).contains(&value) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

// ---------------------------------------------------------------------------------------------
// Series styles

/// Okabe and Ito's colour-blind-safe palette without its yellow, which is unreadable on
/// white; black last.
const COLOURS: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

#[derive(Debug, Clone, Copy, PartialEq)]
enum Marker {
    Circle,
    Square,
    TriangleUp,
    Diamond,
    TriangleDown,
    Plus,
}

const MARKERS: [Marker; 6] = [
    Marker::Circle,
    Marker::Square,
    Marker::TriangleUp,
    Marker::Diamond,
    Marker::TriangleDown,
    Marker::Plus,
];

#[derive(Debug, Clone, Copy, PartialEq)]
struct SeriesStyle {
    colour: RGBColor,
    marker: Marker,
}

/// One style per distinct label, the same in every panel. A label's first word picks its
/// colour and its last word its marker, each in order of first appearance: "stratified cpu" and
/// "stratified gpu" share a colour, "stratified gpu" and "cosine gpu" a marker, so a chart of
/// strategies × backends reads as a grid. Colours and markers cycle past their lists.
fn series_styles(panels: &[ChartPanel]) -> Vec<(String, SeriesStyle)> {
    let mut first_words: Vec<&str> = Vec::new();
    let mut last_words: Vec<&str> = Vec::new();
    let mut styles: Vec<(String, SeriesStyle)> = Vec::new();
    for series in panels.iter().flat_map(|p| &p.series) {
        if styles.iter().any(|(label, _)| *label == series.label) {
            continue;
        }
        let first = series.label.split_whitespace().next().unwrap_or("");
        let last = series.label.split_whitespace().last().unwrap_or("");
        let colour = position_or_push(&mut first_words, first);
        let marker = position_or_push(&mut last_words, last);
        let style = SeriesStyle {
            colour: COLOURS[colour % COLOURS.len()],
            marker: MARKERS[marker % MARKERS.len()],
        };
        styles.push((series.label.clone(), style));
    }
    styles
}

/// Index of `word` in `words`, appended first if new.
fn position_or_push<'a>(words: &mut Vec<&'a str>, word: &'a str) -> usize {
    match words.iter().position(|w| *w == word) {
        Some(i) => i,
        None => {
            words.push(word);
            words.len() - 1
        }
    }
}

fn style_of(styles: &[(String, SeriesStyle)], label: &str) -> SeriesStyle {
    styles
        .iter()
        .find(|(l, _)| l == label)
        .map(|(_, s)| *s)
        .expect("series_styles saw every label")
}

/// A position in pixels, what plotters calls `BackendCoord` (a type it does not re-export).
type BackendCoord = (i32, i32);

/// Half the width of a marker, in pixels.
const MARKER_RADIUS: i32 = 5;

/// The outline of a marker around (0, 0), in pixels, y down. Every marker is a polygon, even
/// the circle, so that all of them are one element type: plotters can only box an element
/// that borrows nothing, and the backends here borrow their output buffers.
fn marker_outline(marker: Marker) -> Vec<BackendCoord> {
    let r = MARKER_RADIUS;
    match marker {
        Marker::Circle => (0..16)
            .map(|i| {
                let angle = f64::from(i) * std::f64::consts::TAU / 16.0;
                let radius = f64::from(r) + 0.5;
                (
                    (radius * angle.cos()).round() as i32,
                    (radius * angle.sin()).round() as i32,
                )
            })
            .collect(),
        Marker::Square => vec![
            (-r + 1, -r + 1),
            (r - 1, -r + 1),
            (r - 1, r - 1),
            (-r + 1, r - 1),
        ],
        Marker::TriangleUp => vec![(0, -r - 1), (r + 1, r), (-r - 1, r)],
        Marker::TriangleDown => vec![(0, r + 1), (r + 1, -r), (-r - 1, -r)],
        Marker::Diamond => vec![(0, -r - 1), (r + 1, 0), (0, r + 1), (-r - 1, 0)],
        // A plus sign with arms three pixels wide.
        Marker::Plus => vec![
            (-1, -r - 1),
            (1, -r - 1),
            (1, -1),
            (r + 1, -1),
            (r + 1, 1),
            (1, 1),
            (1, r + 1),
            (-1, r + 1),
            (-1, 1),
            (-r - 1, 1),
            (-r - 1, -1),
            (-1, -1),
        ],
    }
}

/// A filled marker centred `offset` pixels from the point it is anchored to.
fn marker_shape(style: SeriesStyle, (dx, dy): BackendCoord) -> Polygon<BackendCoord> {
    let outline = marker_outline(style.marker)
        .into_iter()
        .map(|(x, y)| (x + dx, y + dy))
        .collect::<Vec<_>>();
    Polygon::new(outline, style.colour.filled())
}

// ---------------------------------------------------------------------------------------------
// Drawing

/// Everything the drawing needs, prepared and checked before any backend exists.
struct Chart<'a> {
    title: &'a str,
    x_label: &'a str,
    panels: &'a [ChartPanel],
    layouts: &'a [PanelLayout],
    styles: Vec<(String, SeriesStyle)>,
}

const TITLE_SIZE: f64 = 28.0;
const CAPTION_SIZE: f64 = 20.0;
const AXIS_LABEL_SIZE: f64 = 16.0;
const TICK_LABEL_SIZE: f64 = 14.0;
const POINT_LABEL_SIZE: f64 = 12.0;
const LEGEND_SIZE: f64 = 15.0;

fn render_svg(chart: &Chart, size: (u32, u32)) -> std::result::Result<Vec<u8>, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(&root, chart).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg.into_bytes())
}

/// Draws into an RGB buffer and encodes it with the `image` crate the crate already uses for
/// previews, rather than plotters' own encoder, which would pull in a second `image` version.
fn render_png(chart: &Chart, (width, height): (u32, u32)) -> std::result::Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut rgb = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
        draw(&root, chart).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    Ok(png)
}

type DrawResult<DB> =
    std::result::Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, chart: &Chart) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let body = root.titled(chart.title, ("sans-serif", TITLE_SIZE))?;
    let areas = body.split_evenly((1, chart.panels.len()));
    for ((area, panel), layout) in areas.iter().zip(chart.panels).zip(chart.layouts) {
        draw_panel(area, chart, panel, layout)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    chart: &Chart,
    panel: &ChartPanel,
    layout: &PanelLayout,
) -> DrawResult<DB> {
    let x_axis = layout
        .x
        .clone()
        .log_scale()
        .with_key_points(layout.x_ticks.clone())
        .with_light_points(minor_ticks(&layout.x));
    let y_axis = layout
        .y
        .clone()
        .log_scale()
        .with_key_points(layout.y_ticks.clone())
        .with_light_points(minor_ticks(&layout.y));
    let mut plot = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", CAPTION_SIZE))
        .margin(12)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x_axis, y_axis)?;

    let label = |v: &f64| tick_label(*v);
    plot.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(&panel.y_label)
        .x_label_formatter(&label)
        .y_label_formatter(&label)
        .axis_desc_style(("sans-serif", AXIS_LABEL_SIZE))
        .label_style(("sans-serif", TICK_LABEL_SIZE))
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(238, 238, 238))
        .draw()?;

    for (index, series) in panel.series.iter().enumerate() {
        let style = style_of(&chart.styles, &series.label);
        let points = drawable_points(series);
        let line = LineSeries::new(
            points.iter().map(|p| (p.seconds, p.error)),
            style.colour.stroke_width(2),
        );
        let legend = if points.is_empty() {
            format!("{} (no data)", series.label)
        } else {
            series.label.clone()
        };
        plot.draw_series(line)?.label(legend).legend(move |(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (24, 0)], style.colour.stroke_width(2))
                + marker_shape(style, (12, 0))
        });
        plot.draw_series(points.iter().map(|p| {
            EmptyElement::at((p.seconds, p.error))
                + marker_shape(style, (0, 0))
                + sample_label(p, style, label_below(index))
        }))?;
    }

    plot.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", LEGEND_SIZE))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(160, 160, 160))
        .draw()?;
    Ok(())
}

/// Alternate series put their sample counts below-left of their points instead of above-right,
/// so that two lines running close together do not print their labels on top of each other.
/// Both corners are off the line itself, which falls from the upper left to the lower right
/// (error drops as time grows).
fn label_below(series_index: usize) -> bool {
    series_index % 2 == 1
}

/// A point's sample count, beside its marker in the series' colour.
fn sample_label(
    point: &ChartPoint,
    style: SeriesStyle,
    below: bool,
) -> Text<'static, BackendCoord, String> {
    let gap = MARKER_RADIUS + 2;
    let (offset, anchor) = if below {
        ((-gap, gap - 2), Pos::new(HPos::Right, VPos::Top))
    } else {
        ((gap, 2 - gap), Pos::new(HPos::Left, VPos::Bottom))
    };
    Text::new(
        point.samples.to_string(),
        offset,
        ("sans-serif", POINT_LABEL_SIZE)
            .into_font()
            .color(&style.colour)
            .pos(anchor),
    )
}

#[cfg(test)]
mod tests;
