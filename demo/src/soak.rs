//! The soak: the networked demo for an hour (or more) over a lossy, jittery delayed link, with
//! figures per minute — process memory and CPU, the rendered-force error, the haptic loop's
//! overruns and skipped ticks, and the outages — written as the run goes.
//!
//! The operator's helper hands every tick and measurement to a [`operator::helper::Tap`]; the
//! run's own recording keeps only the first minute, so memory stays flat however long the run.
//! [`Minutes`] cuts the samples into minutes of ticks and computes each minute's figures with
//! the report's own code ([`metrics::networked::figures`]) once the minute's measurements have
//! come back (a few round trips after its last tick), then forgets them.
//!
//! What it is not: a benchmark. Every process of the system runs in this one process, so the
//! memory and CPU figures are the whole system's (telerobot, shim, operator, soak monitor).

pub mod cmd;

use std::sync::Arc;

use metrics::NodeInfo;
use metrics::networked::{MeasurementSample, NetworkedRun, TickSample};
use operator::helper::Tapped;
use serde::Serialize;
use transport::Outages;

/// One minute's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Minute {
    /// Minute number, from the haptic loop's tick 0.
    pub minute: u64,
    /// Ticks recorded in the minute (60,000 at 1 kHz when none was skipped).
    pub ticks: u64,
    /// Measurements whose command lies in the minute.
    pub measurements: u64,
    /// Share of the minute's ticks the operator was in contact \[%\].
    pub in_contact_pct: f64,
    /// RMS error of the rendered force, % of the RMS measured force, over the minute's ticks
    /// from the first contact in it (the report's `rms_error_pct`).
    pub error_pct: Option<f64>,
    /// The same from the time the operator renders a model (the report's after-stable figure).
    pub error_after_stable_pct: Option<f64>,
    /// Times in the minute without measurements for 100 ms or more (by arrival).
    pub outages: u64,
    /// Longest of them \[ms\].
    pub longest_outage_ms: f64,
    /// Haptic-loop ticks that started more than half a period late, since the last row.
    pub overruns: u64,
    /// Haptic-loop ticks given up after stalls, since the last row.
    pub skipped_ticks: u64,
    /// Resident memory of the process when the row was written \[MB\].
    pub rss_mb: f64,
    /// CPU time of the process since the last row, % of one core.
    pub cpu_pct: f64,
    /// New model ids the operator took in the minute: the first contact's, then one each time
    /// the telerobot's estimator reset its model (a new object, or a misfit taken for one).
    #[serde(default)]
    pub models: u64,
}

/// Cuts tapped samples into minutes and computes each minute's figures.
#[derive(Debug)]
pub struct Minutes {
    run: NetworkedRun,
    timing: Option<Arc<rt::LoopTiming>>,
    /// Ticks per minute.
    per_minute: u64,
    /// Time to wait after a minute's last tick before its figures (its measurements' round
    /// trip) \[s\], and the same in ticks.
    lag_s: f64,
    lag_ticks: u64,
    next: u64,
    ticks: Vec<TickSample>,
    measurements: Vec<MeasurementSample>,
    /// Arrival times not yet counted \[ns\].
    arrivals: Vec<i64>,
    /// Ticks at which a new model id was taken, not yet counted.
    models: Vec<u64>,
    /// The last arrival before the current minute (an outage across the boundary counts).
    last_arrival_ns: Option<i64>,
    counted: (u64, u64),
}

impl Minutes {
    /// Minutes of a run named `experiment` with `set_delay_ms` one way: each minute's figures
    /// wait `lag_s` of ticks after its end for its last measurements.
    pub fn new(experiment: &str, set_delay_ms: f64, lag_s: f64) -> Minutes {
        Minutes {
            run: NetworkedRun {
                experiment: experiment.to_owned(),
                set_delay_ms: Some(set_delay_ms),
                ..NetworkedRun::default()
            },
            timing: None,
            per_minute: 0,
            lag_s: lag_s.max(0.0),
            lag_ticks: 0,
            next: 0,
            ticks: Vec::new(),
            measurements: Vec::new(),
            arrivals: Vec::new(),
            models: Vec::new(),
            last_arrival_ns: None,
            counted: (0, 0),
        }
    }

    /// Takes one tapped message; returns the minutes it completed (memory and CPU left zero).
    pub fn take(&mut self, tapped: Tapped) -> Vec<Minute> {
        match tapped {
            Tapped::Start {
                start_ns,
                period_ns,
                timing,
            } => {
                self.run.start_ns = start_ns;
                self.run.period_ns = period_ns.max(1);
                self.per_minute = (60_000_000_000 / self.run.period_ns).max(1) as u64;
                self.lag_ticks = (self.lag_s * 1e9 / self.run.period_ns as f64) as u64;
                self.timing = Some(timing);
                Vec::new()
            }
            Tapped::Batch {
                ticks,
                measurements,
                models,
            } => {
                self.ticks.extend(ticks);
                self.models.extend(models.iter().map(|m| m.0));
                self.arrivals
                    .extend(measurements.iter().map(|m| m.received_ns));
                self.measurements.extend(measurements);
                let mut done = Vec::new();
                while self.per_minute > 0
                    && self.ticks.last().is_some_and(|t| {
                        t.index >= (self.next + 1) * self.per_minute + self.lag_ticks
                    })
                {
                    done.push(self.close());
                }
                done
            }
        }
    }

    /// The figures of the minute not yet closed, however far it got (the end of the run).
    pub fn finish(&mut self) -> Option<Minute> {
        let first = self.next * self.per_minute;
        (self.per_minute > 0 && self.ticks.iter().any(|t| t.index >= first)).then(|| self.close())
    }

    /// The figures of minute `self.next`; forgets its samples.
    fn close(&mut self) -> Minute {
        let (first, end) = (
            self.next * self.per_minute,
            (self.next + 1) * self.per_minute,
        );
        let start_ns = self.run.start_ns + first as i64 * self.run.period_ns;
        let end_ns = self.run.start_ns + end as i64 * self.run.period_ns;
        let ticks: Vec<TickSample> = self
            .ticks
            .iter()
            .filter(|t| (first..end).contains(&t.index))
            .map(|t| TickSample {
                index: t.index - first,
                ..*t
            })
            .collect();
        let in_minute =
            |m: &MeasurementSample| (start_ns..end_ns).contains(&m.command_sample_time_ns);
        let measurements: Vec<MeasurementSample> = self
            .measurements
            .iter()
            .copied()
            .filter(in_minute)
            .collect();
        let run = NetworkedRun {
            start_ns,
            ..self.run.clone()
        };
        let (_, figures) =
            metrics::networked::figures(&run, &ticks, &measurements, NodeInfo::default());
        let outages = self.outages(start_ns, end_ns);
        let (overruns, skipped) = self.loop_counts();
        let contact = ticks.iter().filter(|t| t.in_contact).count();
        let models = self.models.iter().filter(|&&k| k < end).count() as u64;
        self.models.retain(|&k| k >= end);
        self.ticks.retain(|t| t.index >= end);
        self.measurements
            .retain(|m| m.command_sample_time_ns >= end_ns);
        self.next += 1;
        Minute {
            minute: self.next - 1,
            ticks: ticks.len() as u64,
            measurements: measurements.len() as u64,
            in_contact_pct: 100.0 * contact as f64 / ticks.len().max(1) as f64,
            error_pct: figures.experiment.rms_error_pct,
            error_after_stable_pct: figures.experiment.rms_error_pct_after_stable,
            outages: outages.count,
            longest_outage_ms: outages.longest_ms,
            overruns,
            skipped_ticks: skipped,
            models,
            ..Minute::default()
        }
    }

    /// Outages in `[from, to)` by the measurements' arrivals, from the last arrival before
    /// `from` (a gap across the boundary counts in the minute it ends in; a minute without any
    /// arrival is one outage).
    fn outages(&mut self, from: i64, to: i64) -> Outages {
        let mut points: Vec<i64> = self.last_arrival_ns.into_iter().collect();
        let mut now: Vec<i64> = self
            .arrivals
            .iter()
            .copied()
            .filter(|t| (from..to).contains(t))
            .collect();
        now.sort_unstable();
        points.extend(now);
        self.arrivals.retain(|&t| t >= to);
        match points.last() {
            Some(&last) => {
                self.last_arrival_ns = Some(last);
                Outages::from_arrivals(&points, to).0
            }
            None => Outages::from_arrivals(&[from], to).0,
        }
    }

    /// Overruns and skipped ticks since the last call.
    fn loop_counts(&mut self) -> (u64, u64) {
        let Some(timing) = &self.timing else {
            return (0, 0);
        };
        let r = timing.report();
        let counts = (
            r.overruns.saturating_sub(self.counted.0),
            r.skipped_ticks.saturating_sub(self.counted.1),
        );
        self.counted = (r.overruns, r.skipped_ticks);
        counts
    }
}

/// The process's resident memory \[MB\] and CPU time \[s\] so far, from `/proc/self` (Linux;
/// `None` elsewhere). CPU time is in `USER_HZ` ticks there, 100 per second on every Linux ABI.
pub fn process_usage() -> Option<(f64, f64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let rss_kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at state, field 3.
    let rest = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((rss_kb / 1024.0, (utime + stime) / 100.0))
}

/// What the whole soak says: the figures the issue asks of it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Verdict {
    /// Full minutes.
    pub minutes: usize,
    /// Resident memory at the end of the second minute and of the last \[MB\].
    pub rss_mb: (f64, f64),
    /// Highest resident memory \[MB\].
    pub rss_max_mb: f64,
    /// Least-squares slope of resident memory from the second minute on \[MB per hour\].
    pub rss_growth_mb_per_h: f64,
    /// Median CPU over the minutes, % of one core.
    pub cpu_median_pct: f64,
    /// Minutes in contact for at least [`Verdict::CONTACT_PCT`] of their ticks: the error
    /// figures below are theirs (a minute that lifts off, or spends it out of contact, has
    /// contact transients or no force to compare: the trajectory lifts off twice in a run).
    pub minutes_in_contact: usize,
    /// Median of the per-minute error after stable \[%\].
    pub error_median_pct: Option<f64>,
    /// Largest distance of a minute's error from the median \[points\].
    pub error_max_deviation_pts: Option<f64>,
    /// Minutes more than 1 point from the median.
    pub minutes_beyond_1_pt: usize,
    /// Overruns, skipped ticks and outages over all minutes.
    pub overruns: u64,
    /// Skipped ticks over all minutes.
    pub skipped_ticks: u64,
    /// Outages over all minutes.
    pub outages: u64,
}

impl Verdict {
    /// The share of a minute's ticks in contact for its error to count \[%\].
    pub const CONTACT_PCT: f64 = 90.0;

    /// The verdict over full minutes `rows` (a last, partial minute left out by the caller).
    pub fn of(rows: &[Minute]) -> Verdict {
        let later: Vec<&Minute> = rows.iter().skip(1).collect();
        let in_contact = rows
            .iter()
            .filter(|r| r.in_contact_pct >= Self::CONTACT_PCT);
        let errors: Vec<f64> = in_contact
            .clone()
            .filter_map(|r| r.error_after_stable_pct)
            .collect();
        let error_median = median(&errors);
        let deviations: Vec<f64> = error_median
            .map(|m| errors.iter().map(|e| (e - m).abs()).collect())
            .unwrap_or_default();
        let cpu: Vec<f64> = rows.iter().map(|r| r.cpu_pct).collect();
        Verdict {
            minutes: rows.len(),
            rss_mb: (
                later.first().map_or(0.0, |r| r.rss_mb),
                rows.last().map_or(0.0, |r| r.rss_mb),
            ),
            rss_max_mb: rows.iter().map(|r| r.rss_mb).fold(0.0, f64::max),
            rss_growth_mb_per_h: slope(&later) * 60.0,
            cpu_median_pct: median(&cpu).unwrap_or(0.0),
            minutes_in_contact: in_contact.count(),
            error_median_pct: error_median,
            error_max_deviation_pts: deviations.iter().copied().reduce(f64::max),
            minutes_beyond_1_pt: deviations.iter().filter(|&&d| d > 1.0).count(),
            overruns: rows.iter().map(|r| r.overruns).sum(),
            skipped_ticks: rows.iter().map(|r| r.skipped_ticks).sum(),
            outages: rows.iter().map(|r| r.outages).sum(),
        }
    }
}

/// The median of `v` (`None` when empty).
fn median(v: &[f64]) -> Option<f64> {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => Some(s[n / 2]),
        _ => Some(0.5 * (s[n / 2 - 1] + s[n / 2])),
    }
}

/// Least-squares slope of memory against the minute number \[MB per minute\] (0 below two rows).
fn slope(rows: &[&Minute]) -> f64 {
    let n = rows.len() as f64;
    if rows.len() < 2 {
        return 0.0;
    }
    let mx = rows.iter().map(|r| r.minute as f64).sum::<f64>() / n;
    let my = rows.iter().map(|r| r.rss_mb).sum::<f64>() / n;
    let sxy: f64 = rows
        .iter()
        .map(|r| (r.minute as f64 - mx) * (r.rss_mb - my))
        .sum();
    let sxx: f64 = rows.iter().map(|r| (r.minute as f64 - mx).powi(2)).sum();
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

#[cfg(test)]
mod tests;
