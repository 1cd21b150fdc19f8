//! The telerobot's command playout: the operator's path is played back at a steady offset from
//! its sample times, so a datagram that overtook others (netem's `reorder` sends it at once, a
//! whole delay early) waits for its turn, a bunch held up by jitter is played in order, and the
//! robot is told a smooth path whatever the arrival times.
//!
//! The playout time is `τ = now − L`. `L` follows a high (90th) percentile of the lag
//! `received − sample_time` over the last 128 arrivals (both clocks' offset is in it and cancels).
//! Every arrival counts toward it, duplicates and stale ones included: if only the commands that
//! were kept counted, early (reordered) arrivals could pull it down, make every command in flight
//! stale, and so keep it down for good. Over a link with jitter J the playout adds up to about
//! 0.8·J of delay; over a steady link (loopback, a fixed netem delay) it is the link's lag.
//!
//! Each tick the robot gets the path at `τ`: the two commands around it interpolated, position
//! and velocity. A command that is late (its turn came before it did) is bridged by extrapolating
//! the last one along its velocity, for at most [`MAX_EXTRAPOLATION_NS`]; then the path stops
//! until it comes. `L` moves toward its estimate by at most [`SLEW`] of the elapsed time, so the
//! path plays at 1 ± 2 % of real time while it moves, and the velocity handed on is scaled by that
//! rate: the position the robot is told and its velocity always agree.
//!
//! Why (issue 11's soak): `L` used to be the estimate itself, re-taken every 16 arrivals, and the
//! robot ran the newest due command. The estimate wobbled across tick boundaries, so about one
//! command in 20 was repeated (the position froze while its velocity said it moved) and the next
//! skipped (a double step). The estimator fed with that motion saw a sustained misfit and reset
//! its model about three times a minute; a real arm would have felt the jerk.
//!
//! A change of the estimate larger than [`LAG_STEP_NS`] is a change of the link, not jitter: `L`
//! takes it at once (when it grows, the path waits; when it shrinks, the commands in between are
//! skipped and counted). When the path has reached no command for [`MAX_WAIT_NS`] while commands
//! are held (the link's delay just dropped and the window has not seen it yet) it jumps to the
//! oldest held; it never interpolates across a gap longer than that. `τ` never goes back.
//! Nothing allocates.

use super::telerobot::CommandSample;

/// Commands held at most (a few tens of milliseconds at 1 kHz).
const PENDING: usize = 64;
/// Lags kept for the percentile.
const LAGS: usize = 128;
/// The percentile of the lag that sets the playout time.
const PERCENTILE: f64 = 0.9;
/// Arrivals between two estimates of the lag.
const ESTIMATE_EVERY: usize = 16;
/// Largest rate at which the playout lag follows its estimate \[1\]: 2 % (20 µs a tick at 1 kHz).
pub(super) const SLEW: f64 = 0.02;
/// A step of the lag estimate beyond which `L` takes it at once \[ns\].
pub(super) const LAG_STEP_NS: i64 = 20_000_000;
/// How far past the newest command the path is extrapolated along its velocity \[ns\].
pub(super) const MAX_EXTRAPOLATION_NS: i64 = 10_000_000;
/// How long the path waits on held commands before jumping to the oldest; the longest gap between
/// two commands it interpolates across \[ns\].
pub(super) const MAX_WAIT_NS: i64 = 50_000_000;

/// Orders and times the commands the telerobot executes.
#[derive(Clone, Debug)]
pub(super) struct Playout {
    pending: [Option<CommandSample>; PENDING],
    lags: [i64; LAGS],
    lag_count: usize,
    lag_head: usize,
    since_estimate: usize,
    /// The estimate of the lag \[ns\].
    lag_ns: Option<i64>,
    /// The estimate `L` last followed \[ns\].
    taken_ns: Option<i64>,
    /// The playout time of the last tick, and that tick's time \[ns\]: `L` as played is their
    /// difference (a jump or a wait moves it too, so the slew goes on from where the path is).
    last: Option<(i64, i64)>,
    /// The newest command whose sample time the path has reached.
    current: Option<CommandSample>,
    last_received_ns: Option<i64>,
    /// When the path last reached a command, or when the first command arrived \[ns\].
    last_progress_ns: Option<i64>,
    /// The path is at rest for want of commands (extrapolated as far as it goes).
    stopped: bool,
}

/// What happened to a pushed command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Push {
    /// Held for its turn.
    Queued,
    /// Older than, or the same as, one already reached or held.
    Stale,
    /// The buffer was full: the oldest held command was dropped to make room.
    Overflow,
}

impl Playout {
    pub(super) fn new() -> Self {
        Playout {
            pending: [None; PENDING],
            lags: [0; LAGS],
            lag_count: 0,
            lag_head: 0,
            since_estimate: 0,
            lag_ns: None,
            taken_ns: None,
            last: None,
            current: None,
            last_received_ns: None,
            last_progress_ns: None,
            stopped: false,
        }
    }

    pub(super) fn push(&mut self, c: CommandSample) -> Push {
        let t = c.sample_time_ns;
        self.record_lag(c.received_ns.saturating_sub(t));
        self.last_received_ns = Some(
            self.last_received_ns
                .map_or(c.received_ns, |r| r.max(c.received_ns)),
        );
        self.last_progress_ns.get_or_insert(c.received_ns);
        if self.current.is_some_and(|cur| t <= cur.sample_time_ns)
            || self.pending.iter().flatten().any(|p| p.sample_time_ns == t)
        {
            return Push::Stale;
        }
        if let Some(slot) = self.pending.iter_mut().find(|p| p.is_none()) {
            *slot = Some(c);
            return Push::Queued;
        }
        // Full: replace the oldest held command.
        if let Some(oldest) = self
            .pending
            .iter_mut()
            .min_by_key(|p| p.map_or(i64::MIN, |p| p.sample_time_ns))
        {
            *oldest = Some(c);
        }
        Push::Overflow
    }

    /// Whether the path handed on by the last [`Self::advance`] was at rest for want of
    /// commands: extrapolated past the newest one as far as [`MAX_EXTRAPOLATION_NS`] goes.
    pub(super) fn stopped(&self) -> bool {
        self.stopped
    }

    /// Adds one arrival's lag and re-estimates it every [`ESTIMATE_EVERY`] arrivals (at once for
    /// the first).
    fn record_lag(&mut self, lag_ns: i64) {
        self.lags[self.lag_head] = lag_ns;
        self.lag_head = (self.lag_head + 1) % LAGS;
        self.lag_count = (self.lag_count + 1).min(LAGS);
        self.since_estimate += 1;
        if self.lag_ns.is_none() || self.since_estimate >= ESTIMATE_EVERY {
            self.since_estimate = 0;
            let mut window = self.lags;
            let n = self.lag_count;
            let k = ((n as f64 * PERCENTILE) as usize).min(n - 1);
            let (_, kth, _) = window[..n].select_nth_unstable(k);
            self.lag_ns = Some(*kth);
        }
    }

    /// The path at `now_ns` (`None` before the first command's turn) and the number of commands
    /// skipped getting there.
    pub(super) fn advance(&mut self, now_ns: i64) -> (Option<CommandSample>, usize) {
        let Some(estimate) = self.lag_ns else {
            return (None, 0);
        };
        let dt = self
            .last
            .map_or(0, |(_, then)| now_ns.saturating_sub(then).max(0));
        let lag = self.follow(estimate, dt);
        let mut tau = now_ns.saturating_sub(lag.round() as i64);
        if let Some((before, _)) = self.last {
            tau = tau.max(before);
        }
        // Nothing reached for MAX_WAIT_NS while commands are held: the link's delay dropped and
        // the estimate has not seen it yet. The path jumps to the oldest held command.
        let starving = self
            .last_progress_ns
            .is_some_and(|t| now_ns.saturating_sub(t) >= MAX_WAIT_NS);
        if starving && let Some(oldest) = self.held().map(|p| p.sample_time_ns).min() {
            tau = tau.max(oldest);
        }
        let reached = self.reach(tau, now_ns);
        // Not across a gap longer than MAX_WAIT_NS (an outage, or a command that overtook the rest
        // by a whole delay): the path goes on from the newest command alone until the jump.
        let next = self
            .held()
            .min_by_key(|p| p.sample_time_ns)
            .copied()
            .filter(|n| {
                self.current.is_none_or(|c| {
                    n.sample_time_ns.saturating_sub(c.sample_time_ns) <= MAX_WAIT_NS
                })
            });
        // With nothing held beyond it, the path goes no further than the extrapolation from the
        // newest command: a stall raises `L` (the path waits where it stopped), and the slew
        // brings it back down, instead of a jump when the commands come again.
        if next.is_none()
            && let Some(c) = self.current
        {
            let limit = c.sample_time_ns.saturating_add(MAX_EXTRAPOLATION_NS);
            tau = tau.min(limit.max(self.last.map_or(limit, |(before, _)| before)));
        }
        self.stopped = next.is_none()
            && self
                .current
                .is_some_and(|c| tau.saturating_sub(c.sample_time_ns) >= MAX_EXTRAPOLATION_NS);
        let advanced = self.last.map_or(0, |(before, _)| tau - before);
        let smooth = advanced as f64 <= (1.0 + SLEW) * dt as f64 + 1.0;
        let rate = match self.last {
            Some(_) if dt > 0 && smooth => advanced as f64 / dt as f64,
            _ => 1.0,
        };
        self.last = Some((tau, now_ns));
        let skipped = if smooth { 0 } else { reached.saturating_sub(1) };
        (self.current.map(|c| path_at(c, next, tau, rate)), skipped)
    }

    /// `L` this tick: the estimate `estimate` taken at once if it stepped by more than
    /// [`LAG_STEP_NS`] since the last tick, else approached by at most [`SLEW`] of `dt`.
    fn follow(&mut self, estimate: i64, dt: i64) -> f64 {
        // A step of the estimate itself is the link's; anything slower is slewed to.
        let step = self
            .taken_ns
            .is_none_or(|t| estimate.saturating_sub(t).saturating_abs() > LAG_STEP_NS);
        self.taken_ns = Some(estimate);
        match self.last {
            Some((tau, then)) if !step => {
                let lag = then.saturating_sub(tau) as f64;
                let most = SLEW * dt as f64;
                lag + (estimate as f64 - lag).clamp(-most, most)
            }
            _ => estimate as f64,
        }
    }

    /// Takes the held commands at or before `tau` off the buffer; the newest becomes the current
    /// one. Returns how many.
    fn reach(&mut self, tau: i64, now_ns: i64) -> usize {
        let mut reached = 0;
        for slot in &mut self.pending {
            if let Some(p) = *slot
                && p.sample_time_ns <= tau
            {
                reached += 1;
                self.last_progress_ns = Some(now_ns);
                if self
                    .current
                    .is_none_or(|c| p.sample_time_ns > c.sample_time_ns)
                {
                    self.current = Some(p);
                }
                *slot = None;
            }
        }
        reached
    }

    fn held(&self) -> impl Iterator<Item = &CommandSample> {
        self.pending.iter().flatten()
    }

    /// `L` as played this tick: the tick's time less the path's playout time \[ns\].
    pub(super) fn played_lag_ns(&self) -> Option<i64> {
        self.last.map(|(tau, now)| now - tau)
    }

    /// When the newest command arrived [ns], if any did.
    pub(super) fn last_received_ns(&self) -> Option<i64> {
        self.last_received_ns
    }

    /// The lag estimate \[ns\], once a command has arrived.
    #[cfg(test)]
    fn lag_ns(&self) -> Option<i64> {
        self.lag_ns
    }
}

/// The path at `tau`, from the newest command reached (`at`) and the next one held, played at
/// `rate` of real time: interpolated between the two, or extrapolated along `at`'s velocity for
/// at most [`MAX_EXTRAPOLATION_NS`] (then still). Named after the nearer of the two commands.
fn path_at(at: CommandSample, next: Option<CommandSample>, tau: i64, rate: f64) -> CommandSample {
    let scale = |v: [f64; 3], s: f64| v.map(|x| x * s);
    let ahead = tau.saturating_sub(at.sample_time_ns);
    match next {
        Some(n) if ahead > 0 => {
            let span = n.sample_time_ns.saturating_sub(at.sample_time_ns).max(1);
            let (position_m, velocity) = hermite(at, n, ahead as f64 / span as f64, span);
            CommandSample {
                sample_time_ns: if 2 * ahead > span {
                    n.sample_time_ns
                } else {
                    at.sample_time_ns
                },
                position_m,
                velocity_m_per_s: scale(velocity, rate),
                received_ns: at.received_ns,
            }
        }
        None if ahead > 0 => {
            let moving = ahead <= MAX_EXTRAPOLATION_NS;
            let reach = ahead.min(MAX_EXTRAPOLATION_NS) as f64 * 1e-9;
            CommandSample {
                position_m: std::array::from_fn(|i| {
                    at.position_m[i] + at.velocity_m_per_s[i] * reach
                }),
                velocity_m_per_s: scale(at.velocity_m_per_s, if moving { rate } else { 0.0 }),
                ..at
            }
        }
        _ => CommandSample {
            velocity_m_per_s: scale(at.velocity_m_per_s, rate),
            ..at
        },
    }
}

/// The cubic Hermite curve from `a` to `b` (positions and velocities at both ends) at `s` of
/// the `span_ns` between them: its position, and its velocity (the curve's own rate). Between
/// commands a tick apart it differs from a straight line by at most `a·dt²/8` (under a µm); across
/// a gap (commands lost, or not read while the operator's loop stalled) the straight line's
/// constant rate and the velocities' blend would disagree by up to the change of velocity over it.
fn hermite(a: CommandSample, b: CommandSample, s: f64, span_ns: i64) -> ([f64; 3], [f64; 3]) {
    let h = span_ns as f64 * 1e-9;
    let (s2, s3) = (s * s, s * s * s);
    let (h00, h10, h01, h11) = (
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        3.0 * s2 - 2.0 * s3,
        s3 - s2,
    );
    let (d00, d10, d01, d11) = (
        6.0 * s2 - 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        6.0 * s - 6.0 * s2,
        3.0 * s2 - 2.0 * s,
    );
    let (p0, v0, p1, v1) = (
        a.position_m,
        a.velocity_m_per_s,
        b.position_m,
        b.velocity_m_per_s,
    );
    (
        std::array::from_fn(|i| h00 * p0[i] + h10 * h * v0[i] + h01 * p1[i] + h11 * h * v1[i]),
        std::array::from_fn(|i| (d00 * p0[i] + d01 * p1[i]) / h + d10 * v0[i] + d11 * v1[i]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// A command on the path `x = t` (t in ms): a speed of 1,000 "m"/s, so a path step of 1 is
    /// one millisecond of it.
    fn cmd(sample_ms: i64, received_ms: i64) -> CommandSample {
        CommandSample {
            sample_time_ns: sample_ms * MS,
            position_m: [sample_ms as f64, 0.0, 0.0],
            velocity_m_per_s: [1e3, 0.0, 0.0],
            received_ns: received_ms * MS,
        }
    }

    #[test]
    fn across_a_gap_the_path_is_the_cubic_through_both_commands_and_moves_at_its_velocity() {
        // x(t) = t³ − 2t (t in s) sampled at 0.1 and 0.121 s (a 21 ms gap): a cubic is
        // reproduced exactly, and the velocity handed on is the path's own rate.
        let x = |t: f64| t * t * t - 2.0 * t;
        let v = |t: f64| 3.0 * t * t - 2.0;
        let at = |t: f64| CommandSample {
            sample_time_ns: (t * 1e9).round() as i64,
            position_m: [x(t), 0.0, 0.0],
            velocity_m_per_s: [v(t), 0.0, 0.0],
            received_ns: 0,
        };
        let (a, b) = (at(0.1), at(0.121));
        for k in 0..=21 {
            let t = 0.1 + k as f64 * 1e-3;
            let p = path_at(a, Some(b), (t * 1e9).round() as i64, 1.0);
            assert!((p.position_m[0] - x(t)).abs() < 1e-15, "{k}: {p:?}");
            assert!((p.velocity_m_per_s[0] - v(t)).abs() < 1e-12, "{k}: {p:?}");
        }
    }

    #[test]
    fn in_order_commands_run_on_arrival() {
        let mut p = Playout::new();
        for k in 0..300 {
            assert_eq!(p.push(cmd(k, k + 50)), Push::Queued);
            let (c, skipped) = p.advance((k + 50) * MS);
            assert_eq!(c.unwrap().sample_time_ns, k * MS);
            assert_eq!(skipped, 0);
        }
    }

    #[test]
    fn a_command_that_overtook_the_others_waits_for_its_turn() {
        let mut p = Playout::new();
        for k in 0..200 {
            p.push(cmd(k, k + 50));
            p.advance((k + 50) * MS);
        }
        // Command 260 arrives at once (50 ms early) at t = 250 + 10.
        for k in 200..300 {
            if k == 210 {
                assert_eq!(p.push(cmd(260, 260)), Push::Queued);
            }
            if k != 260 {
                assert_eq!(
                    p.push(cmd(k, k + 50)),
                    Push::Queued,
                    "command {k} must not be stale"
                );
            }
            let (c, _) = p.advance((k + 50) * MS);
            assert_eq!(c.unwrap().sample_time_ns, k * MS, "executing in order");
        }
    }

    #[test]
    fn a_command_a_whole_delay_early_is_not_steered_toward() {
        let mut p = Playout::new();
        for k in 0..200 {
            p.push(cmd(k, k + 50));
            p.advance((k + 50) * MS);
        }
        // Command 250 overtook the rest (reorder), and 200–204 are late: the path goes on
        // along 199's velocity for 10 ms and waits, instead of heading for 250.
        p.push(cmd(250, 250));
        for now in 250..265 {
            let (c, _) = p.advance(now * MS);
            let x = c.unwrap().position_m[0];
            assert!(x <= 209.0 + 1e-9, "at {now}: the path is at {x}");
        }
        for k in 200..215 {
            p.push(cmd(k, 265));
        }
        let (c, _) = p.advance(265 * MS);
        let x = c.unwrap().position_m[0];
        assert!(x < 211.0, "resumed at {x}, lag {:?}", p.lag_ns());
    }

    #[test]
    fn duplicates_and_old_commands_are_stale() {
        let mut p = Playout::new();
        p.push(cmd(1, 2));
        p.advance(2 * MS);
        assert_eq!(p.push(cmd(1, 3)), Push::Stale);
        assert_eq!(p.push(cmd(0, 3)), Push::Stale);
        assert_eq!(p.push(cmd(5, 6)), Push::Queued);
        assert_eq!(p.push(cmd(5, 7)), Push::Stale);
    }

    #[test]
    fn a_backlog_is_played_in_order_without_a_jump_and_the_lag_recovers() {
        let mut p = Playout::new();
        for k in 0..100 {
            p.push(cmd(k, k + 5));
            p.advance((k + 5) * MS);
        }
        // A 20 ms stall, then everything at once: the path goes on along the last command's
        // velocity for 10 ms, waits there, then plays the bunch in order, one path step a tick
        // at most 1 + SLEW of a millisecond: nothing is skipped, nothing jumps.
        let mut last = 99.0;
        let mut skipped = 0;
        // The slew takes the 10 ms the path fell behind back at 2 %: in half a second.
        for now in 105..1500 {
            let k = now - 5;
            if (100..120).contains(&k) {
                if k == 119 {
                    for j in 100..120 {
                        p.push(cmd(j, 125));
                    }
                }
            } else if k >= 120 {
                p.push(cmd(k, now));
            }
            let (c, s) = p.advance(now * MS);
            skipped += s;
            let x = c.unwrap().position_m[0];
            assert!(x >= last, "in order at {now}: {x} after {last}");
            assert!(
                x - last <= 1.0 + SLEW + 1e-9,
                "a jump at {now}: {last} → {x}"
            );
            last = x;
        }
        assert_eq!(skipped, 0);
        assert_eq!(p.lag_ns(), Some(5 * MS), "the stall is forgotten");
        p.push(cmd(1495, 1500));
        let (c, _) = p.advance(1500 * MS);
        assert_eq!(
            c.unwrap().sample_time_ns,
            1495 * MS,
            "back to running on arrival"
        );
    }

    #[test]
    fn early_arrivals_at_the_start_do_not_hold_the_lag_down() {
        // The first commands to arrive overtook the others (lag 0); every later one takes 50 ms.
        let mut p = Playout::new();
        let mut stale = 0;
        for k in 0..400 {
            let received = if k < 5 { k } else { k + 50 };
            if k >= 5 && p.push(cmd(k, received)) == Push::Stale {
                stale += 1;
            }
            if k < 5 {
                p.push(cmd(k + 50, received));
            }
            p.advance(received * MS);
        }
        assert_eq!(p.lag_ns(), Some(50 * MS));
        assert!(stale <= 50, "{stale} commands dropped as stale");
        let (c, _) = p.advance(449 * MS);
        assert_eq!(c.unwrap().sample_time_ns, 399 * MS);
    }

    #[test]
    fn jitter_that_keeps_order_is_played_not_skipped() {
        // netem's jitter without reordering: each command is delayed 50 ± 5 ms but never
        // overtakes the one before, so arrivals come in bunches.
        let mut p = Playout::new();
        let (mut arrived, mut rng) = (0_i64, 0x2545_f491_4f6c_dd1d_u64);
        let mut arrivals = Vec::new();
        for k in 0..3000_i64 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let jitter_us = (rng % 10_001) as i64 - 5_000;
            arrived = arrived.max(k * 1000 + 50_000 + jitter_us);
            arrivals.push((k, arrived));
        }
        let (mut skipped, mut next, mut last) = (0, 0, -1);
        for tick_us in (0..3_100_000_i64).step_by(1000) {
            while next < arrivals.len() && arrivals[next].1 <= tick_us {
                p.push(CommandSample {
                    received_ns: tick_us * 1000,
                    ..cmd(arrivals[next].0, 0)
                });
                next += 1;
            }
            let (c, s) = p.advance(tick_us * 1000);
            skipped += s;
            if let Some(c) = c {
                assert!(c.sample_time_ns >= last);
                last = c.sample_time_ns;
            }
        }
        assert_eq!(last, 2999 * MS);
        assert!(skipped < 150, "{skipped} of 3000 commands skipped");
    }

    #[test]
    fn a_drop_in_the_links_delay_holds_the_robot_back_only_briefly() {
        let mut p = Playout::new();
        for k in 0..300 {
            p.push(cmd(k, k + 200));
            p.advance((k + 200) * MS);
        }
        // The delay drops from 200 ms to 1 ms: commands from 500 on arrive at once.
        let (mut last_run, mut last) = (500, 299);
        for now in 500..1200 {
            p.push(cmd(now - 1, now));
            let (c, _) = p.advance(now * MS);
            let t = c.unwrap().sample_time_ns / MS;
            if t != last {
                last_run = now;
                last = t;
            }
            assert!(
                now - last_run <= MAX_WAIT_NS / MS,
                "held since {last_run} at {now}"
            );
        }
        assert_eq!(p.lag_ns(), Some(MS));
        assert_eq!(last, 1198, "running on arrival again");
    }
}
