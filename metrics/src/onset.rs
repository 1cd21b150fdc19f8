//! What happens at contact onsets (issue 13): how soon a force is felt, how soon the error
//! settles, and the error just after each re-contact.

use mmt::vec3;

use crate::Series;

/// The windows [`settle_s`] judges the error in \[s\].
pub const SETTLE_WINDOW_S: f64 = 0.25;
/// The error every window after settling stays within \[%\].
pub const SETTLE_PCT: f64 = 10.0;
/// How long after each re-contact [`recontact_error_pct`] looks \[s\].
pub const RECONTACT_S: f64 = 1.0;

/// From the first tick of local contact to the first tick at or after it with a non-zero
/// rendered force \[ms\].
pub(crate) fn first_force_ms(s: &Series) -> Option<f64> {
    let onset = s.contact_local.iter().position(|c| *c)?;
    let ticks = s.rendered[onset..]
        .iter()
        .position(|f| vec3::norm2(*f) > 0.0)?;
    Some(ticks as f64 * s.dt_s() * 1e3)
}

/// From the first true contact until the error stays within [`SETTLE_PCT`] in every
/// [`SETTLE_WINDOW_S`] window to the end \[s\]. Only windows in true contact for at least half
/// their ticks, with a measured force above 0.05 N RMS, are judged: in free space the measured
/// force is the sensor's noise, and 0 rendered is right. `None` with no contact, or when the
/// last judged window is still beyond the bound.
pub fn settle_s(s: &Series) -> Option<f64> {
    let first = s.contact_true.iter().position(|c| *c == Some(true))?;
    let per = ((SETTLE_WINDOW_S / s.dt_s()).round() as usize).max(1);
    let mut settled_from = None;
    for start in (first..s.len()).step_by(per) {
        let end = (start + per).min(s.len());
        let touching = (start..end)
            .filter(|&i| s.contact_true[i] == Some(true))
            .count();
        if 2 * touching < end - start {
            continue;
        }
        match window_pct(s, start, end) {
            Some(e) if e > SETTLE_PCT => settled_from = None,
            Some(_) if settled_from.is_none() => settled_from = Some(start),
            _ => {}
        }
    }
    settled_from.map(|i| (i - first) as f64 * s.dt_s())
}

/// The RMS error over the [`RECONTACT_S`] after each true contact onset but the first, pooled
/// \[%\]; `None` with fewer than two contacts.
pub fn recontact_error_pct(s: &Series) -> Option<f64> {
    let per = (RECONTACT_S / s.dt_s()).round() as usize;
    let onsets: Vec<usize> = (1..s.len())
        .filter(|&i| s.contact_true[i] == Some(true) && s.contact_true[i - 1] == Some(false))
        .collect();
    let (mut e2, mut m2) = (0.0, 0.0);
    for &onset in onsets.iter().skip(1) {
        let (e, m) = sums(s, onset, (onset + per).min(s.len()));
        e2 += e;
        m2 += m;
    }
    (m2 > 0.0).then(|| 100.0 * (e2 / m2).sqrt())
}

/// The error of each stage of what the operator renders, over the ticks in true contact.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StageErrors {
    /// Before any model of the object: the prior (or nothing) \[%\].
    pub prior_pct: Option<f64>,
    /// The telerobot's reduced first model (massless) \[%\].
    pub reduced_pct: Option<f64>,
    /// The whole model \[%\].
    pub whole_pct: Option<f64>,
    /// Time in contact in each stage, in that order \[s\].
    pub seconds: [f64; 3],
}

/// The RMS error of each stage ([`StageErrors`]): a tick in true contact is the prior's while
/// the operator renders no model, the reduced model's while it renders that, the whole
/// model's otherwise; each stage's error is relative to the measured force in its own ticks.
pub fn stage_errors(s: &Series) -> StageErrors {
    let mut sums = [(0.0, 0.0, 0usize); 3];
    for i in 0..s.len() {
        let (Some(true), Some(m)) = (s.contact_true[i], s.measured[i]) else {
            continue;
        };
        let rendering = s.rendering.get(i).copied().unwrap_or(false);
        let stage = match (rendering, s.reduced.get(i).copied().unwrap_or(false)) {
            (false, _) => 0,
            (true, true) => 1,
            (true, false) => 2,
        };
        let (e2, m2, n) = &mut sums[stage];
        *e2 += vec3::norm2(vec3::sub(s.rendered[i], m));
        *m2 += vec3::norm2(m);
        *n += 1;
    }
    let pct = |(e2, m2, _): (f64, f64, usize)| (m2 > 0.0).then(|| 100.0 * (e2 / m2).sqrt());
    StageErrors {
        prior_pct: pct(sums[0]),
        reduced_pct: pct(sums[1]),
        whole_pct: pct(sums[2]),
        seconds: sums.map(|(_, _, n)| n as f64 * s.dt_s()),
    }
}

/// The error in ticks `start..end` \[%\]; `None` when the measured force's RMS is 0.05 N or less.
pub(crate) fn window_pct(s: &Series, start: usize, end: usize) -> Option<f64> {
    let (e2, m2) = sums(s, start, end);
    let n = (start..end).filter(|&i| s.measured[i].is_some()).count();
    let rms = if n > 0 { (m2 / n as f64).sqrt() } else { 0.0 };
    (rms > 0.05).then(|| 100.0 * (e2 / m2).sqrt())
}

/// Σ|rendered − measured|² and Σ|measured|² over ticks `start..end` with a measurement.
fn sums(s: &Series, start: usize, end: usize) -> (f64, f64) {
    let (mut e2, mut m2) = (0.0, 0.0);
    for i in start..end {
        if let Some(m) = s.measured[i] {
            e2 += vec3::norm2(vec3::sub(s.rendered[i], m));
            m2 += vec3::norm2(m);
        }
    }
    (e2, m2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A series of `n` ticks at 1 kHz, in contact on `contact`, measuring 1 N on x and
    /// rendering `rendered(i)` on x.
    fn series(
        n: usize,
        contact: impl Fn(usize) -> bool,
        rendered: impl Fn(usize) -> f64,
    ) -> Series {
        let mut s = Series::with_capacity(n, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], 1_000_000);
        for i in 0..n {
            let c = contact(i);
            s.rendered.push([rendered(i), 0.0, 0.0]);
            s.contact_local.push(c);
            s.contact_true[i] = Some(c);
            s.measured[i] = Some(if c { [1.0, 0.0, 0.0] } else { [0.0; 3] });
        }
        s
    }

    #[test]
    fn the_error_settles_when_every_window_after_is_within_the_bound() {
        // Contact from tick 100; the rendered force is 0 until tick 600, then exact but for a
        // 20 % error in ticks 1,100–1,349 (one whole window, from the first contact's grid).
        let s = series(
            3000,
            |i| i >= 100,
            |i| match i {
                0..600 => 0.0,
                1100..1350 => 1.2,
                _ => 1.0,
            },
        );
        assert_eq!(settle_s(&s), Some(1.25));
        assert_eq!(first_force_ms(&s), Some(500.0));
        // Never settled: the last window is wrong.
        let s = series(1000, |i| i >= 100, |i| if i >= 850 { 0.5 } else { 1.0 });
        assert_eq!(settle_s(&s), None);
        // Settled from the first window: 0 s.
        let s = series(1000, |i| i >= 100, |_| 1.05);
        assert_eq!(settle_s(&s), Some(0.0));
        // Free space with a noisy sensor (0.1 N measured, 0 rendered) is not judged.
        let mut s = series(
            3000,
            |i| !(1000..2000).contains(&i),
            |i| {
                if (1000..2000).contains(&i) { 0.0 } else { 1.0 }
            },
        );
        for m in &mut s.measured[1000..2000] {
            *m = Some([0.1, 0.0, 0.0]);
        }
        assert_eq!(settle_s(&s), Some(0.0));
    }

    #[test]
    fn the_recontact_error_pools_the_second_after_each_onset_but_the_first() {
        // Contacts at 100–1,999, 3,000–4,999 and 6,000–7,999; renders 1.5 N in the first 500
        // ticks of each contact, 1 N after.
        let contact = |i: usize| (100..2000).contains(&i) || (3000..5000).contains(&i) || i >= 6000;
        let onset = |i: usize| [100, 3000, 6000].into_iter().filter(|&o| o <= i).max();
        let s = series(9000, contact, |i| match onset(i) {
            Some(o) if contact(i) && i - o < 500 => 1.5,
            Some(_) if contact(i) => 1.0,
            _ => 0.0,
        });
        // Over 2 × 1,000 ticks: 2 × 500 with 0.5 N of error: √(500·0.25·2 / 2000) = 35.4 %.
        let e = recontact_error_pct(&s).unwrap();
        assert!((e - 100.0 * 0.125_f64.sqrt()).abs() < 1e-9, "{e}");
        let once = series(3000, |i| i >= 100, |_| 1.0);
        assert_eq!(recontact_error_pct(&once), None);
    }

    #[test]
    fn each_stage_is_judged_on_its_own_ticks_in_contact() {
        // Contact from tick 100; no model until 600 (renders 0.5 N: a soft prior), the reduced
        // model until 1,000 (0.9 N), the whole one after (1 N), and a break 2,000–2,499 that
        // renders 3 N out of contact (not judged).
        let contact = |i: usize| i >= 100 && !(2000..2500).contains(&i);
        let mut s = series(4000, contact, |i| match i {
            0..600 => 0.5,
            600..1000 => 0.9,
            2000..2500 => 3.0,
            _ => 1.0,
        });
        s.rendering = (0..4000).map(|i| i >= 600).collect();
        s.reduced = (0..4000).map(|i| (600..1000).contains(&i)).collect();
        let e = stage_errors(&s);
        let close = |a: Option<f64>, b: f64| (a.unwrap() - b).abs() < 1e-9;
        assert!(close(e.prior_pct, 50.0), "{e:?}");
        assert!(close(e.reduced_pct, 10.0), "{e:?}");
        assert!(close(e.whole_pct, 0.0), "{e:?}");
        assert!((e.seconds[0] - 0.5).abs() < 1e-12 && (e.seconds[1] - 0.4).abs() < 1e-12);
        assert!((e.seconds[2] - 2.5).abs() < 1e-9, "{e:?}");
        // Without a reduced stage or a prior stage: None, not 0.
        s.rendering = vec![true; 4000];
        s.reduced = vec![false; 4000];
        let e = stage_errors(&s);
        assert_eq!((e.prior_pct, e.reduced_pct), (None, None));
    }
}
