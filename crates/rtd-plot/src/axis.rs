//! Axis ticks: a few round values across a range, their compact labels, and the plotters axis
//! that draws grid lines and labels at exactly those values.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

/// A linear axis over [lo, hi] (axis units) whose grid lines and labels fall on given ticks.
pub(crate) struct TickedAxis {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
}

impl TickedAxis {
    pub(crate) fn new(lo: f64, hi: f64, ticks: Vec<f64>) -> Self {
        TickedAxis { lo, hi, ticks }
    }
}

impl Ranged for TickedAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value - self.lo) / (self.hi - self.lo);
        limit.0 + (t * (limit.1 - limit.0) as f64).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        // Only the bold grid (labelled) gets points; there is no light grid between them.
        match hint.weight() {
            plotters::coord::ranged1d::KeyPointWeight::Bold if hint.max_num_points() > 0 => self.ticks.clone(),
            _ => vec![],
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// Round tick positions across [lo, hi], in axis units (log10 of the value on a log axis): on a
/// linear axis 4 to 8 multiples of 1, 2 or 5 × 10^k; on a log axis the decades, with 2× and 5×
/// steps between them when the range spans under three decades, every other decade past
/// eight, and the range's own ends when it holds no decade at all.
pub fn ticks(lo: f64, hi: f64, log: bool) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return vec![];
    }
    if !log {
        return linear_ticks(lo, hi);
    }
    let decades = (lo.ceil() as i64)..=(hi.floor() as i64);
    let span = hi - lo;
    let steps: &[f64] = if span < 1.2 {
        &[1.0, 1.5, 2.0, 3.0, 5.0, 7.0]
    } else if span < 3.0 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    let every = ((decades.clone().count() as f64 / 8.0).ceil() as i64).max(1);
    let mut out = vec![];
    for d in (lo.floor() as i64)..=(hi.ceil() as i64) {
        if steps.len() == 1 && d.rem_euclid(every) != 0 {
            continue;
        }
        for m in steps {
            let v = d as f64 + m.log10();
            if v >= lo && v <= hi {
                out.push(v);
            }
        }
    }
    if out.len() < 2 {
        // Too narrow for round values: the linear ticks of the values, in log units.
        return linear_ticks(10f64.powf(lo), 10f64.powf(hi)).into_iter().filter(|v| *v > 0.0).map(f64::log10).collect();
    }
    out
}

fn linear_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let raw = (hi - lo) / 6.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * mag).find(|s| (hi - lo) / s <= 8.0).unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

/// A tick value as a short label: up to three significant digits without trailing zeros
/// ("0.5", "20", "1500"), and powers of ten as "1e-4" or "2e6" outside 0.001..100000.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 { "0".into() } else { format!("{v}") };
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        let e = a.log10().floor();
        let m = v / 10f64.powf(e);
        let m = format!("{:.2}", m);
        let m = m.trim_end_matches('0').trim_end_matches('.');
        return format!("{m}e{}", e as i64);
    }
    // Three significant digits, then trailing zeros and a bare point dropped.
    let decimals = (2 - a.log10().floor() as i64).clamp(0, 6) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values(lo: f64, hi: f64) -> Vec<f64> {
        ticks(lo.log10(), hi.log10(), true).iter().map(|t| (10f64.powf(*t) * 1e6).round() / 1e6).collect()
    }

    #[test]
    fn log_ticks_are_round_and_few() {
        // 0.5 s to 30 s: 1-2-5 steps.
        assert_eq!(values(0.5, 30.0), [0.5, 1.0, 2.0, 5.0, 10.0, 20.0]);
        // 8 to 10 s (the old plot's overlapping "8·9·10.0"): a handful of labels, spaced on a
        // 540-px axis wider than any label (about 30 px).
        let narrow = values(8.0, 10.0);
        let t = ticks(8f64.log10(), 1.0, true);
        let gap = t.windows(2).map(|w| (w[1] - w[0]) / (1.0 - 8f64.log10()) * 540.0).fold(f64::INFINITY, f64::min);
        assert!((2..=6).contains(&narrow.len()) && gap > 60.0, "{narrow:?}: {gap} px apart");
        // Ten decades: every other one, at most 8 labels.
        let wide = values(1e-6, 1e4);
        assert!(wide.len() <= 8 && wide.contains(&1.0), "{wide:?}");
        assert!(wide.windows(2).all(|w| w[1] > w[0]));
    }

    #[test]
    fn linear_ticks_are_multiples_of_a_round_step() {
        assert_eq!(ticks(0.0, 100.0, false), [0.0, 20.0, 40.0, 60.0, 80.0, 100.0]);
        assert_eq!(ticks(31.2, 33.9, false), [31.5, 32.0, 32.5, 33.0, 33.5]);
        assert!(ticks(1.0, 1.0, false).is_empty());
    }

    #[test]
    fn labels_are_short() {
        let cases =
            [(0.5, "0.5"), (20.0, "20"), (1500.0, "1500"), (1e-4, "1e-4"), (2e6, "2e6"), (33.25, "33.2"), (0.0, "0")];
        for (v, s) in cases {
            assert_eq!(tick_label(v), s, "{v}");
        }
    }
}
