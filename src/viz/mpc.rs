//! The receding-horizon controller's figure: the histogram of its per-tick solve times
//! against the tick period (the deadline a solve must meet for its policy to reach the
//! robot within one tick).

use super::plots::{plot_error, FONT, PALETTE, PANEL_HEIGHT, WIDTH};
use super::VizError;
use plotters::prelude::*;
use std::path::Path;

/// Counts of `times_ms` in `bins` equal bins over `[0, hi)` (the last bin takes `hi` and
/// above).
pub fn histogram(times_ms: &[f64], hi: f64, bins: usize) -> Vec<usize> {
    let mut counts = vec![0; bins.max(1)];
    let width = hi / counts.len() as f64;
    for &t in times_ms.iter().filter(|t| t.is_finite()) {
        let i = ((t.max(0.0) / width) as usize).min(counts.len() - 1);
        counts[i] += 1;
    }
    counts
}

/// The histogram of the ticks' solve times (seconds in `times`), the tick period as a red
/// line, the median and 99th percentile in the caption, into an SVG.
pub fn write_tick_time_histogram(times: &[f64], period: f64, title: &str, path: impl AsRef<Path>) -> Result<(), VizError> {
    let path = path.as_ref();
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let ms: Vec<f64> = times.iter().map(|t| t * 1e3).collect();
    let period_ms = period * 1e3;
    let largest = ms.iter().copied().fold(0.0, f64::max);
    let hi = (largest.max(period_ms) * 1.1).max(1e-3);
    let bins = 60;
    let counts = histogram(&ms, hi, bins);
    let width = hi / bins as f64;
    let top = counts.iter().copied().max().unwrap_or(0).max(1) as f64 * 1.1;
    let p50 = crate::mpc::closed_loop::percentile(times.to_vec(), 50.0) * 1e3;
    let p99 = crate::mpc::closed_loop::percentile(times.to_vec(), 99.0) * 1e3;
    let over = ms.iter().filter(|t| **t > period_ms).count();
    let caption = format!("{title}: {} ticks, median {p50:.2} ms, p99 {p99:.2} ms, {over} over the {period_ms:.1} ms period", ms.len());
    let root = SVGBackend::new(path, (WIDTH, 2 * PANEL_HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, (FONT, 18))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..hi, 0.0..top)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("solve time per tick (ms)")
        .y_desc("ticks")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(RGBColor(238, 240, 243))
        .bold_line_style(RGBColor(214, 218, 224))
        .draw()
        .map_err(|e| err(&e))?;
    chart
        .draw_series(counts.iter().enumerate().filter(|(_, c)| **c > 0).map(|(i, c)| Rectangle::new([(i as f64 * width, 0.0), ((i + 1) as f64 * width, *c as f64)], PALETTE[0].filled())))
        .map_err(|e| err(&e))?;
    chart.draw_series(std::iter::once(PathElement::new(vec![(period_ms, 0.0), (period_ms, top)], RED.stroke_width(2)))).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_counts_every_tick_once() {
        let counts = histogram(&[0.1, 0.2, 1.5, 9.0, 12.0], 10.0, 10);
        assert_eq!(counts.iter().sum::<usize>(), 5);
        assert_eq!(counts[0], 2);
        assert_eq!(counts[1], 1);
        assert_eq!(counts[9], 2);
    }

    #[test]
    fn the_histogram_names_its_percentiles_and_the_period() {
        let path = std::env::temp_dir().join(format!("legwork-ticks-{}.svg", std::process::id()));
        let times: Vec<f64> = (1..=100).map(|i| i as f64 * 1e-4).collect();
        write_tick_time_histogram(&times, 0.005, "gallop", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.contains("100 ticks, median 5.00 ms, p99 9.90 ms, 50 over the 5.0 ms period"), "{svg}");
        std::fs::remove_file(&path).ok();
    }
}
