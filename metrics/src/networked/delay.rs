//! `measured_delay_ms`: how far the rendered force leads the measured one (network notes §5.4).
//!
//! The operator renders the tangential force at its tick times `t0 + k·T`; the telerobot measures
//! it at its own tick times, stamped on its clock. Mapped onto the operator's clock with the
//! clock-offset estimate θ (`t_operator = t_telerobot − θ`) and resampled onto the operator's tick
//! grid (linear interpolation, gaps over 5 ticks left out), the measured signal is the rendered
//! one shifted by the command's one-way trip: the uplink delay, plus the telerobot's wait for its
//! next tick. The lag of the peak of their normalised cross-correlation (Pearson per lag, over the
//! ticks where both exist), refined by a parabola through the peak and its neighbours, is that
//! delay.

/// Longest gap between two measurements interpolated across \[ticks\].
const MAX_GAP_TICKS: f64 = 5.0;
/// Smallest peak correlation accepted: below it the signals do not match well enough to say.
const MIN_PEAK: f64 = 0.5;

/// Lags searched \[s\]: from `-before_s` (measured ahead: only with a wrong clock offset) to
/// `after_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LagRange {
    /// Largest lead of measured over rendered searched \[s\].
    pub before_s: f64,
    /// Largest lag of measured behind rendered searched \[s\].
    pub after_s: f64,
}

impl Default for LagRange {
    fn default() -> Self {
        LagRange {
            before_s: 0.1,
            after_s: 2.5,
        }
    }
}

/// The result: the lag and how well the shifted signals match.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct DelayEstimate {
    /// Lag of measured behind rendered \[ms\].
    pub delay_ms: f64,
    /// Correlation at the peak, in \[−1, 1\].
    pub peak_correlation: f64,
    /// Tick pairs at the peak's lag.
    pub pairs: usize,
}

/// Estimates the lag of `measured` behind `rendered`.
///
/// - `rendered\[k\]`: the rendered tangential force at tick `k` (used only where `use_tick\[k\]`);
/// - `measured`: `(u, value)`, `u` the measurement's time on the operator's clock in ticks since
///   tick 0 (fractional), any order;
/// - `period_s`: the tick period.
pub fn estimate(
    rendered: &[f64],
    use_tick: &[bool],
    measured: &[(f64, f64)],
    period_s: f64,
    range: LagRange,
) -> Option<DelayEstimate> {
    let n = rendered.len();
    if n == 0 || use_tick.len() != n || !(period_s > 0.0) {
        return None;
    }
    let grid = resample(measured, n);
    let lo = -((range.before_s / period_s).round() as i64);
    let hi = (range.after_s / period_s).round() as i64;
    let scores: Vec<Option<(f64, usize)>> = (lo..=hi)
        .map(|lag| correlation(rendered, use_tick, &grid, lag))
        .collect();
    let (best, &(peak, pairs)) = scores
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.as_ref().map(|s| (i, s)))
        .max_by(|a, b| a.1.0.total_cmp(&b.1.0))?;
    if peak < MIN_PEAK {
        return None;
    }
    let lag_ticks = (lo + best as i64) as f64 + parabola_shift(&scores, best, peak);
    Some(DelayEstimate {
        delay_ms: lag_ticks * period_s * 1e3,
        peak_correlation: peak,
        pairs,
    })
}

/// Pearson correlation of `rendered` (on the ticks in `use_tick`) with the resampled measured
/// signal `grid` shifted by `lag` ticks, and the pairs it is over; `None` under 100 pairs or
/// for a constant signal.
fn correlation(
    rendered: &[f64],
    use_tick: &[bool],
    grid: &[Option<f64>],
    lag: i64,
) -> Option<(f64, usize)> {
    let (mut sr, mut sm, mut srr, mut smm, mut srm, mut count) = (0.0, 0.0, 0.0, 0.0, 0.0, 0usize);
    for k in 0..rendered.len() {
        if !use_tick[k] {
            continue;
        }
        let j = k as i64 + lag;
        let Some(m) = usize::try_from(j)
            .ok()
            .and_then(|j| grid.get(j).copied().flatten())
        else {
            continue;
        };
        let r = rendered[k];
        sr += r;
        sm += m;
        srr += r * r;
        smm += m * m;
        srm += r * m;
        count += 1;
    }
    if count < 100 {
        return None;
    }
    let c = count as f64;
    let cov = srm - sr * sm / c;
    let var = (srr - sr * sr / c) * (smm - sm * sm / c);
    (var > 0.0).then(|| (cov / var.sqrt(), count))
}

/// The peak's offset in ticks, within ±0.5, from the parabola through the peak (`peak` at
/// index `best` of `scores`) and its neighbours; 0 without both neighbours or a maximum.
fn parabola_shift(scores: &[Option<(f64, usize)>], best: usize, peak: f64) -> f64 {
    let at = |i: Option<usize>| {
        i.and_then(|i| scores.get(i).copied().flatten())
            .map(|s| s.0)
    };
    match (at(best.checked_sub(1)), at(Some(best + 1))) {
        (Some(before), Some(after)) => {
            let curvature = before - 2.0 * peak + after;
            if curvature < 0.0 {
                (0.5 * (before - after) / curvature).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        }
        _ => 0.0,
    }
}

/// The measured samples on the tick grid `0..n` (linear interpolation between neighbours at most
/// [`MAX_GAP_TICKS`] apart).
fn resample(measured: &[(f64, f64)], n: usize) -> Vec<Option<f64>> {
    let mut points: Vec<(f64, f64)> = measured
        .iter()
        .copied()
        .filter(|(u, v)| u.is_finite() && v.is_finite())
        .collect();
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut grid = vec![None; n];
    for pair in points.windows(2) {
        let [(u0, v0), (u1, v1)] = [pair[0], pair[1]];
        if u1 - u0 > MAX_GAP_TICKS || u1 <= u0 {
            continue;
        }
        let first = u0.ceil().max(0.0) as usize;
        let mut k = first;
        while (k as f64) <= u1 && k < n {
            let w = (k as f64 - u0) / (u1 - u0);
            grid[k] = Some(v0 + w * (v1 - v0));
            k += 1;
        }
    }
    grid
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A multisine like the exp-1 excitation, sampled at `t` \[s\].
    fn signal(t: f64) -> f64 {
        [
            (0.35, 1.0, 0.1),
            (0.9, 0.6, 1.0),
            (2.0, 0.3, 2.0),
            (3.6, 0.2, 0.5),
        ]
        .iter()
        .map(|(f, a, p)| a * (2.0 * std::f64::consts::PI * f * t + p).sin())
        .sum()
    }

    #[test]
    fn finds_a_fractional_delay_on_a_shifted_and_jittered_clock() {
        let period = 1e-3;
        let n = 10_000;
        let rendered: Vec<f64> = (0..n).map(|k| signal(k as f64 * period)).collect();
        for delay_ms in [0.0, 0.6, 100.3, 400.7] {
            // Measured at the telerobot's ticks (offset by 0.37 ticks from ours), a few lost.
            let measured: Vec<(f64, f64)> = (0..n)
                .filter(|j| j % 97 != 0)
                .map(|j| {
                    let u = j as f64 + 0.37;
                    (u, signal(u * period - delay_ms * 1e-3))
                })
                .collect();
            let e = estimate(
                &rendered,
                &vec![true; n],
                &measured,
                period,
                LagRange::default(),
            )
            .unwrap();
            assert!((e.delay_ms - delay_ms).abs() < 0.1, "{delay_ms} ms: {e:?}");
            assert!(e.peak_correlation > 0.99);
        }
    }

    #[test]
    fn unrelated_or_missing_signals_give_no_estimate() {
        let n = 2000;
        let rendered: Vec<f64> = (0..n).map(|k| signal(k as f64 * 1e-3)).collect();
        let noise: Vec<(f64, f64)> = (0..n)
            .map(|k| (k as f64, ((k * 7919) % 101) as f64 - 50.0))
            .collect();
        let range = LagRange::default();
        assert!(estimate(&rendered, &vec![true; n], &noise, 1e-3, range).is_none());
        assert!(estimate(&rendered, &vec![true; n], &[], 1e-3, range).is_none());
        assert!(estimate(&[], &[], &noise, 1e-3, range).is_none());
    }
}
