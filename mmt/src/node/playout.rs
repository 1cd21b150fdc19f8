//! The telerobot's command playout: commands are executed in sample-time order, each when its
//! turn comes, so a datagram that overtook others (netem's `reorder` sends it at once, a whole
//! delay early) waits instead of making every command behind it look stale.
//!
//! A command's turn comes when `sample_time + L ≤ now`, `L` a low (10th) percentile of the lag
//! `received − sample_time` over the last 128 commands (both clocks' offset is in it and cancels).
//! In-order commands over a steady link arrive exactly on their turn and run at once; late ones
//! run on arrival; only commands earlier than most wait. Duplicates and commands older than the
//! one executing are dropped. Nothing allocates.

use super::telerobot::CommandSample;

/// Commands held at most (a few tens of milliseconds at 1 kHz).
const PENDING: usize = 64;
/// Lags kept for the percentile.
const LAGS: usize = 128;
/// The percentile of the lag that sets the playout time.
const PERCENTILE: f64 = 0.1;
/// A command waiting longer than this past its arrival runs regardless [ns]: the lag estimate
/// must never hold the robot back for long.
const MAX_WAIT_NS: i64 = 50_000_000;

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
        }
    }

    pub(super) fn push(&mut self, c: CommandSample) -> Push {
        let t = c.sample_time_ns;
        if self.current.is_some_and(|cur| t <= cur.sample_time_ns)
            || self.pending.iter().flatten().any(|p| p.sample_time_ns == t)
        {
            return Push::Stale;
        }
        self.last_received_ns = Some(
            self.last_received_ns
                .map_or(c.received_ns, |r| r.max(c.received_ns)),
        );
        self.lags[self.lag_head] = c.received_ns - t;
        self.lag_head = (self.lag_head + 1) % LAGS;
        self.lag_count = (self.lag_count + 1).min(LAGS);
        self.since_estimate += 1;
        if self.lag_ns.is_none() || self.since_estimate >= 32 {
            self.since_estimate = 0;
            let mut window = self.lags;
            let n = self.lag_count;
            let k = ((n as f64 * PERCENTILE) as usize).min(n - 1);
            let (_, kth, _) = window[..n].select_nth_unstable(k);
            self.lag_ns = Some(*kth);
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

    /// The command to execute at `now_ns` (the newest whose turn has come; older ones are
    /// skipped), and the number skipped.
    pub(super) fn advance(&mut self, now_ns: i64) -> (Option<CommandSample>, usize) {
        let due = self.lag_ns.map_or(i64::MAX, |lag| now_ns - lag);
        let ready =
            |p: &CommandSample| p.sample_time_ns <= due || now_ns - p.received_ns >= MAX_WAIT_NS;
        let newest = self
            .pending
            .iter()
            .flatten()
            .filter(|p| ready(p))
            .map(|p| p.sample_time_ns)
            .max();
        let mut skipped = 0;
        if let Some(newest) = newest {
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
    fn a_backlog_is_skipped_not_replayed() {
        let mut p = Playout::new();
        for k in 0..100 {
            p.push(cmd(k, k + 5));
            p.advance((k + 5) * MS);
        }
        // A 20 ms stall, then everything at once.
        for k in 100..120 {
            p.push(cmd(k, 125));
        }
        let (c, skipped) = p.advance(125 * MS);
        assert_eq!(c.unwrap().sample_time_ns, 119 * MS);
        assert_eq!(skipped, 19);
    }
}
