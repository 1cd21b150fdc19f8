//! `measured_delay_ms`: how far the rendered force leads the measured one (network notes §5.4).
//!
//! The operator renders the tangential force when each tick runs (it reads the device then: at
//! its deadline `t0 + k·T`, or later after a stall); the telerobot measures it at its own tick
//! times, stamped on its clock. Mapped onto the operator's clock with the clock-offset estimate θ
//! (`t_operator = t_telerobot − θ`), both are resampled onto the operator's tick grid (linear
//! interpolation, gaps over 5 ticks left out). The measured signal is then the rendered one
//! shifted by the command's one-way trip: the uplink delay, plus the telerobot's wait for its
//! next tick. The lag of the peak of their normalised cross-correlation (Pearson per lag, over the
//! ticks where both exist), refined by a parabola through the peak and its neighbours, is that
//! delay.
//!
//! Placing a rendered sample at its tick's deadline instead counted each tick's lateness as link
//! delay: 4–13 ms on a loaded two-core machine, whose loop catches up after stalls.

/// Longest gap between two measurements interpolated across \[ticks\].
const MAX_GAP_TICKS: f64 = 5.0;
/// Smallest peak correlation accepted: below it the signals do not match well enough to say.
const MIN_PEAK: f64 = 0.5;
/// Longest run estimated \[ticks\]: the operator records at most an hour at 1 kHz.
const MAX_TICKS: usize = 3_600_000;

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

/// Estimates the lag of `measured` behind `rendered`. Both are `(u, value)`, `u` the time on the
/// operator's clock in ticks since tick 0's deadline (fractional), any order:
///
/// - `rendered`: the rendered tangential force, where a model is rendered;
/// - `measured`: the measured one;
/// - `period_s`: the tick period.
pub fn estimate(
    rendered: &[(f64, f64)],
    measured: &[(f64, f64)],
    period_s: f64,
    range: LagRange,
) -> Option<DelayEstimate> {
    let last = rendered
        .iter()
        .map(|p| p.0)
        .filter(|u| u.is_finite())
        .max_by(f64::total_cmp)?;
    if !(period_s > 0.0) || last < 0.0 {
        return None;
    }
    // Bounded: a garbage time must not size the grid.
    let n = last.floor().min(MAX_TICKS as f64) as usize + 1;
    let rendered: Vec<(usize, f64)> = resample(rendered, n)
        .into_iter()
        .enumerate()
        .filter_map(|(k, r)| Some((k, r?)))
        .collect();
    let grid = resample(measured, n);
    let lo = -((range.before_s / period_s).round() as i64);
    let hi = (range.after_s / period_s).round() as i64;
    let scores: Vec<Option<(f64, usize)>> = (lo..=hi)
        .map(|lag| correlation(&rendered, &grid, lag))
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

/// Pearson correlation of the resampled rendered signal (`(tick, value)` where it exists) with
/// the resampled measured signal `grid` shifted by `lag` ticks, and the pairs it is over; `None`
/// under 100 pairs or for a constant signal.
fn correlation(rendered: &[(usize, f64)], grid: &[Option<f64>], lag: i64) -> Option<(f64, usize)> {
    let (mut sr, mut sm, mut srr, mut smm, mut srm, mut count) = (0.0, 0.0, 0.0, 0.0, 0.0, 0usize);
    for &(k, r) in rendered {
        let j = k as i64 + lag;
        let Some(m) = usize::try_from(j)
            .ok()
            .and_then(|j| grid.get(j).copied().flatten())
        else {
            continue;
        };
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
        let rendered: Vec<(f64, f64)> = (0..n)
            .map(|k| (k as f64, signal(k as f64 * period)))
            .collect();
        for delay_ms in [0.0, 0.6, 100.3, 400.7] {
            // Measured at the telerobot's ticks (offset by 0.37 ticks from ours), a few lost.
            let measured: Vec<(f64, f64)> = (0..n)
                .filter(|j| j % 97 != 0)
                .map(|j| {
                    let u = j as f64 + 0.37;
                    (u, signal(u * period - delay_ms * 1e-3))
                })
                .collect();
            let e = estimate(&rendered, &measured, period, LagRange::default()).unwrap();
            assert!((e.delay_ms - delay_ms).abs() < 0.1, "{delay_ms} ms: {e:?}");
            assert!(e.peak_correlation > 0.99);
        }
    }

    /// CI at stop 27's code: a loaded machine's loop stalls, then catches up its ticks within
    /// microseconds; each tick renders (and stamps its command) when it reads the device. Placed
    /// at their deadlines, the rendered samples made the estimate the delay plus the mean
    /// lateness: 10.9 ms measured at 0 ms set. At their read times it is the delay.
    #[test]
    fn a_stalling_loops_lateness_is_not_counted_as_delay() {
        let period = 1e-3;
        let n = 20_000u32;
        // Every 100 ticks the loop stalls 30 ms, then runs the missed ticks 10 µs apart.
        let mut read = Vec::new();
        let mut free_at = 0.0f64;
        for k in 0..n {
            let due = f64::from(k);
            let stall = if k % 100 == 0 { 30.0 } else { 0.0 };
            let at = due.max(free_at) + stall;
            free_at = at + 0.01;
            read.push(at);
        }
        let lateness: f64 = read
            .iter()
            .zip(0..n)
            .map(|(r, k)| r - f64::from(k))
            .sum::<f64>();
        let mean_late_ms = lateness / f64::from(n) * period * 1e3;
        assert!(
            mean_late_ms > 4.0,
            "the case is a late loop: {mean_late_ms} ms"
        );
        let rendered: Vec<(f64, f64)> = read.iter().map(|&u| (u, signal(u * period))).collect();
        let delay_ms = 100.3;
        let measured: Vec<(f64, f64)> = (0..n)
            .map(|j| {
                let u = f64::from(j) + 0.37;
                (u, signal(u * period - delay_ms * 1e-3))
            })
            .collect();
        let e = estimate(&rendered, &measured, period, LagRange::default()).unwrap();
        assert!((e.delay_ms - delay_ms).abs() < 0.2, "{e:?}");
        // The old placement, for the record: off by about the mean lateness.
        let at_deadlines: Vec<(f64, f64)> = (0..n)
            .zip(&rendered)
            .map(|(k, &(_, v))| (f64::from(k), v))
            .collect();
        let old = estimate(&at_deadlines, &measured, period, LagRange::default()).unwrap();
        assert!(old.delay_ms - delay_ms > 3.0, "{old:?}");
    }

    /// Garbage times change nothing (the grid stops at an hour of ticks, and a lone far sample
    /// has no neighbour to interpolate with); one alone gives no estimate.
    #[test]
    fn non_finite_or_huge_times_are_bounded() {
        let rendered: Vec<(f64, f64)> = (0..2000)
            .map(|k| (f64::from(k), signal(f64::from(k) * 1e-3)))
            .chain([(f64::NAN, 1.0), (f64::INFINITY, 2.0), (1e300, 3.0)])
            .collect();
        let range = LagRange::default();
        let clean = estimate(&rendered[..2000], &rendered[..2000], 1e-3, range).unwrap();
        assert!(clean.delay_ms.abs() < 0.1, "{clean:?}");
        let e = estimate(&rendered, &rendered[..2000], 1e-3, range);
        assert_eq!(e, Some(clean));
        assert!(estimate(&[(f64::NAN, 1.0)], &rendered, 1e-3, range).is_none());
        assert!(estimate(&[(-5.0, 1.0)], &rendered, 1e-3, range).is_none());
    }

    #[test]
    fn unrelated_or_missing_signals_give_no_estimate() {
        let n = 2000;
        let rendered: Vec<(f64, f64)> = (0..n)
            .map(|k| (k as f64, signal(k as f64 * 1e-3)))
            .collect();
        let noise: Vec<(f64, f64)> = (0..n)
            .map(|k| (k as f64, ((k * 7919) % 101) as f64 - 50.0))
            .collect();
        let range = LagRange::default();
        assert!(estimate(&rendered, &noise, 1e-3, range).is_none());
        assert!(estimate(&rendered, &[], 1e-3, range).is_none());
        assert!(estimate(&[], &noise, 1e-3, range).is_none());
    }
}
