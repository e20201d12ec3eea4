//! Tests of `chart`.

use super::*;
use crate::testing::entries;

/// Error falling as 1/sqrt(samples), time growing with samples, per strategy and backend.
fn series(label: &str, seconds_per_sample: f64, error_scale: f64) -> ChartSeries {
    ChartSeries {
        label: label.to_string(),
        points: [16u32, 64, 256, 1024, 4096]
            .iter()
            .map(|&samples| ChartPoint {
                seconds: 0.02 + seconds_per_sample * f64::from(samples),
                error: error_scale / f64::from(samples).sqrt(),
                samples,
            })
            .collect(),
    }
}

fn two_panels() -> Vec<ChartPanel> {
    let three = |scale: f64| {
        vec![
            series("stratified cpu", 0.004, 0.6 * scale),
            series("stratified gpu", 0.0002, 0.6 * scale),
            series("uniform cpu", 0.004, 1.0 * scale),
        ]
    };
    vec![
        ChartPanel {
            title: "Shadowed transfer".to_string(),
            y_label: "RMS error".to_string(),
            series: three(1.0),
        },
        ChartPanel {
            title: "Relit colour".to_string(),
            y_label: "max error".to_string(),
            series: three(0.05),
        },
    ]
}

#[test]
fn svg_names_every_series_and_sample_count() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chart.svg");
    draw_chart(&path, "Speed vs accuracy", "bake time (s)", &two_panels()).unwrap();
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.starts_with("<svg"), "{}", &svg[..60.min(svg.len())]);
    for text in [
        "Speed vs accuracy",
        "Shadowed transfer",
        "Relit colour",
        "bake time (s)",
        "RMS error",
        "stratified cpu",
        "stratified gpu",
        "uniform cpu",
    ] {
        assert!(svg.contains(text), "no {text:?} in the SVG");
    }
    // plotters writes each text element's content on a line of its own.
    let lines: Vec<&str> = svg.lines().map(str::trim).collect();
    for samples in ["16", "64", "256", "1024", "4096"] {
        assert!(
            lines.contains(&samples),
            "no sample-count label {samples} in the SVG"
        );
    }
}

#[test]
fn png_has_the_chart_size_and_is_not_blank() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chart.png");
    draw_chart(&path, "Speed vs accuracy", "bake time (s)", &two_panels()).unwrap();
    let image = image::open(&path).unwrap().to_rgb8();
    assert_eq!(image.dimensions(), (1400, 600));
    let first = *image.get_pixel(0, 0);
    let differing = image.pixels().filter(|p| **p != first).count();
    // Lines, markers, grid and text: far more than a handful of pixels.
    assert!(
        differing > 10_000,
        "only {differing} pixels differ from the background"
    );
    // Some pixel is in a series colour, so the lines were drawn, not just the frame.
    let blue = image::Rgb([0, 114, 178]);
    assert!(
        image.pixels().any(|p| *p == blue),
        "no pixel of the first series"
    );
}

#[test]
fn unknown_extension_is_an_option_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chart.pdf");
    let err = draw_chart(&path, "t", "x", &two_panels()).unwrap_err();
    assert!(matches!(err, Error::Options(_)), "{err}");
    assert!(err.to_string().contains(".svg or .png"), "{err}");
    assert!(
        entries(dir.path()).is_empty(),
        "left behind: {:?}",
        entries(dir.path())
    );
}

#[test]
fn panel_without_a_drawable_point_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty-panel.svg");
    let mut panels = two_panels();
    for series in &mut panels[1].series {
        for point in &mut series.points {
            point.error = -point.error;
        }
    }
    panels[1].series[0].points[0].error = 0.0;
    panels[1].series[1].points[0].seconds = f64::NAN;
    let err = draw_chart(&path, "t", "x", &panels).unwrap_err();
    let message = err.to_string();
    assert!(message.contains("Relit colour"), "{message}");
    assert!(message.contains("positive, finite"), "{message}");
    assert!(
        entries(dir.path()).is_empty(),
        "left behind: {:?}",
        entries(dir.path())
    );
}

#[test]
fn a_series_with_nothing_to_draw_says_so_in_the_legend() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-data.svg");
    let mut panels = two_panels();
    for point in &mut panels[0].series[2].points {
        point.seconds = 0.0;
    }
    draw_chart(&path, "t", "x", &panels).unwrap();
    let svg = std::fs::read_to_string(&path).unwrap();
    assert!(svg.contains("uniform cpu (no data)"));
}

#[test]
fn no_panels_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("none.svg");
    assert!(draw_chart(&path, "t", "x", &[]).is_err());
    assert!(
        entries(dir.path()).is_empty(),
        "left behind: {:?}",
        entries(dir.path())
    );
}

#[test]
fn ticks_are_round_and_inside_the_range() {
    assert_eq!(
        log_ticks(&(0.05..0.5), MAX_TICKS),
        vec![0.05, 0.1, 0.2, 0.5]
    );
    assert_eq!(log_ticks(&(0.95..3.5), MAX_TICKS), vec![1.0, 2.0, 3.0]);
    assert_eq!(
        log_ticks(&(1e-6..1e2), MAX_TICKS),
        vec![1e-6, 1e-4, 1e-2, 1.0, 100.0]
    );
    let wide = log_ticks(&(1e-300..1e300), MAX_TICKS);
    assert!(!wide.is_empty() && wide.len() <= MAX_TICKS, "{wide:?}");
}

#[test]
fn tick_labels_are_short() {
    assert_eq!(tick_label(tick_value(3, -1)), "0.3");
    assert_eq!(tick_label(tick_value(2, -2)), "0.02");
    assert_eq!(tick_label(tick_value(5, 2)), "500");
    assert_eq!(tick_label(tick_value(5, -4)), "0.0005");
    assert_eq!(tick_label(tick_value(1, -5)), "1e-5");
    assert_eq!(tick_label(tick_value(2, 6)), "2e6");
}

#[test]
fn ranges_ignore_points_that_cannot_be_drawn_and_pad_the_rest() {
    let panel = ChartPanel {
        title: "p".to_string(),
        y_label: "e".to_string(),
        series: vec![ChartSeries {
            label: "s".to_string(),
            points: vec![
                ChartPoint {
                    seconds: 0.1,
                    error: 0.01,
                    samples: 4,
                },
                ChartPoint {
                    seconds: 10.0,
                    error: 0.001,
                    samples: 16,
                },
                ChartPoint {
                    seconds: -1.0,
                    error: 1e9,
                    samples: 1,
                },
                ChartPoint {
                    seconds: f64::INFINITY,
                    error: 1e-9,
                    samples: 2,
                },
            ],
        }],
    };
    let layout = PanelLayout::of(&panel).unwrap();
    assert!(
        layout.x.start < 0.1 && layout.x.start > 0.05,
        "{:?}",
        layout.x
    );
    assert!(layout.x.end > 10.0 && layout.x.end < 30.0, "{:?}", layout.x);
    assert!(
        layout.y.start < 0.001 && layout.y.start > 1e-4,
        "{:?}",
        layout.y
    );
    assert!(layout.y.end > 0.01 && layout.y.end < 0.1, "{:?}", layout.y);
}

#[test]
fn extreme_values_keep_finite_ranges_and_few_ticks() {
    let panel = ChartPanel {
        title: "p".to_string(),
        y_label: "e".to_string(),
        series: vec![ChartSeries {
            label: "s".to_string(),
            points: vec![
                ChartPoint {
                    seconds: 1e-300,
                    error: 1e300,
                    samples: 1,
                },
                ChartPoint {
                    seconds: 1e300,
                    error: 1e-300,
                    samples: 2,
                },
            ],
        }],
    };
    let layout = PanelLayout::of(&panel).unwrap();
    for range in [&layout.x, &layout.y] {
        assert!(range.start > 0.0 && range.end.is_finite(), "{range:?}");
    }
    assert!(!layout.x_ticks.is_empty() && layout.x_ticks.len() <= MAX_TICKS);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("extreme.png");
    draw_chart(&path, "t", "x", &[panel]).unwrap();
    assert!(path.exists());
}

#[test]
fn a_single_point_gets_a_range_with_ticks() {
    let layout = PanelLayout::of(&ChartPanel {
        title: "p".to_string(),
        y_label: "e".to_string(),
        series: vec![ChartSeries {
            label: "s".to_string(),
            points: vec![ChartPoint {
                seconds: 2.0,
                error: 0.3,
                samples: 64,
            }],
        }],
    })
    .unwrap();
    assert!(layout.x.contains(&2.0) && layout.y.contains(&0.3));
    assert!(layout.x_ticks.len() >= 2 && layout.y_ticks.len() >= 2);
}

#[test]
fn labels_style_by_their_first_and_last_words() {
    // "stratified cpu", "stratified gpu", "uniform cpu", in both panels.
    let panels = two_panels();
    let styles = series_styles(&panels);
    assert_eq!(styles.len(), 3);
    let (stratified_cpu, stratified_gpu, uniform_cpu) = (styles[0].1, styles[1].1, styles[2].1);
    assert_eq!(stratified_cpu.colour, stratified_gpu.colour);
    assert_ne!(stratified_cpu.marker, stratified_gpu.marker);
    assert_ne!(stratified_cpu.colour, uniform_cpu.colour);
    assert_eq!(stratified_cpu.marker, uniform_cpu.marker);
}
