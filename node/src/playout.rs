//! The telerobot's command playout: commands are executed in sample-time order, each when its
//! turn comes, so a datagram that overtook others (netem's `reorder` sends it at once, a whole
//! delay early) waits instead of making every command behind it look stale, and a bunch of
//! commands held up by jitter is played one per tick instead of being skipped.
//!
//! A command's turn comes when `sample_time + L ≤ now`, `L` a high (90th) percentile of the lag
//! `received − sample_time` over the last 128 arrivals (both clocks' offset is in it and cancels).
//! Every arrival counts toward `L`, duplicates and stale ones included: if only the commands that
//! were kept counted, early (reordered) arrivals could pull `L` down, make every command in
//! flight stale, and so keep it down for good. A high percentile makes the jitter buffer a real
//! one: over a link with jitter J the playout adds up to about 0.8·J of delay and plays commands
//! evenly; over a steady link (loopback, a fixed netem delay) `L` is the link's lag and in-order
//! commands run on arrival. Late ones (the slowest tenth) run on arrival unless a newer one has
//! run; duplicates and commands older than the one executing are dropped. If `L` is too high
//! (the link's delay just dropped) commands are not held back for long: when nothing has run
//! for [`MAX_WAIT_NS`] the oldest held command runs, until the window has caught up with the new
//! lag. Nothing allocates.

use super::telerobot::CommandSample;

/// Commands held at most (a few tens of milliseconds at 1 kHz).
const PENDING: usize = 64;
/// Lags kept for the percentile.
const LAGS: usize = 128;
/// The percentile of the lag that sets the playout time.
const PERCENTILE: f64 = 0.9;
/// Arrivals between two estimates of `L`.
const ESTIMATE_EVERY: usize = 16;
/// The longest the robot waits on held commands before running the oldest regardless [ns].
pub(super) const MAX_WAIT_NS: i64 = 50_000_000;

/// Orders and times the commands the telerobot executes.
#[derive(Clone, Debug)]
pub(super) struct Playout {
    pending: [Option<CommandSample>; PENDING],
    lags: [i64; LAGS],
    lag_count: usize,
    lag_head: usize,
    since_estimate: usize,
    lag_ns: Option<i64>,
    current: Option<CommandSample>,
    last_received_ns: Option<i64>,
    /// When a command last started executing, or when the first command arrived [ns].
    last_progress_ns: Option<i64>,
}

/// What happened to a pushed command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Push {
    /// Held for its turn.
    Queued,
    /// Older than, or the same as, one already executed or held.
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
            current: None,
            last_received_ns: None,
            last_progress_ns: None,
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

    /// Adds one arrival's lag and re-estimates `L` every [`ESTIMATE_EVERY`] arrivals (at once
    /// for the first).
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

    /// The command to execute at `now_ns` — the newest whose turn has come (older ones are
    /// skipped), or the oldest held one if nothing has run for [`MAX_WAIT_NS`] — and the number
    /// skipped.
    pub(super) fn advance(&mut self, now_ns: i64) -> (Option<CommandSample>, usize) {
        let due = self
            .lag_ns
            .map_or(i64::MAX, |lag| now_ns.saturating_sub(lag));
        let held = || self.pending.iter().flatten();
        let newest_due = held().map(|p| p.sample_time_ns).filter(|&t| t <= due).max();
        let starving = self
            .last_progress_ns
            .is_some_and(|t| now_ns.saturating_sub(t) >= MAX_WAIT_NS);
        let run_to = newest_due.or_else(|| {
            starving
                .then(|| held().map(|p| p.sample_time_ns).min())
                .flatten()
        });
        let mut skipped = 0;
        if let Some(newest) = run_to {
            self.last_progress_ns = Some(now_ns);
            for slot in &mut self.pending {
                if let Some(p) = *slot
                    && p.sample_time_ns <= newest
                {
                    if p.sample_time_ns == newest {
                        self.current = Some(p);
                    } else {
                        skipped += 1;
                    }
                    *slot = None;
                }
            }
        }
        (self.current, skipped)
    }

    /// When the newest command arrived [ns], if any did.
    pub(super) fn last_received_ns(&self) -> Option<i64> {
        self.last_received_ns
    }

    /// The playout lag `L` [ns], once a command has arrived.
    #[cfg(test)]
    fn lag_ns(&self) -> Option<i64> {
        self.lag_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn cmd(sample_ms: i64, received_ms: i64) -> CommandSample {
        CommandSample {
            sample_time_ns: sample_ms * MS,
            position_m: [sample_ms as f64, 0.0, 0.0],
            velocity_m_per_s: [0.0; 3],
            received_ns: received_ms * MS,
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
    fn a_backlog_is_skipped_up_to_its_turn_and_the_lag_recovers() {
        let mut p = Playout::new();
        for k in 0..100 {
            p.push(cmd(k, k + 5));
            p.advance((k + 5) * MS);
        }
        // A 20 ms stall, then everything at once: the stall's lags raise L for a while, so the
        // oldest of the bunch are skipped up to the new turn and the rest play one per tick.
        for k in 100..120 {
            p.push(cmd(k, 125));
        }
        let (c, skipped) = p.advance(125 * MS);
        let first = c.unwrap().sample_time_ns / MS;
        assert!((105..119).contains(&first), "ran {first}");
        assert_eq!(skipped as i64, first - 100);
        let mut last = first;
        for k in 120..500 {
            p.push(cmd(k, k + 5));
            let (c, _) = p.advance((k + 5) * MS);
            let now = c.unwrap().sample_time_ns / MS;
            assert!(now >= last, "in order");
            last = now;
        }
        assert_eq!(p.lag_ns(), Some(5 * MS), "the stall is forgotten");
        assert_eq!(last, 499, "back to running on arrival");
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
