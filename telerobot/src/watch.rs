//! What the housekeeping thread watches in the loop's snapshots and tells: the motion guard's
//! work (once per episode: the loop only counts) and the gaps in the commands (outages across
//! sessions).

use crate::control::LoopSnapshot;

/// Logs the motion guard's work once per episode (the loop only counts).
#[derive(Debug, Default)]
pub(crate) struct GuardLog {
    logged: node::GuardStats,
    implausible: u64,
    implausible_session: u64,
}

impl GuardLog {
    pub(crate) fn update(&mut self, s: &LoopSnapshot) {
        let (g, was) = (s.guard, self.logged);
        for (name, now, before) in [
            ("workspace box", g.workspace, was.workspace),
            ("largest step per tick", g.step, was.step),
            ("largest speed", g.speed, was.speed),
        ] {
            if now.episodes > before.episodes {
                tracing::warn!(
                    session = s.session,
                    limit = name,
                    episodes = now.episodes,
                    ticks = now.ticks,
                    "a motion limit clamped the commanded motion"
                );
            }
        }
        if g.faults > was.faults {
            tracing::error!(
                session = s.session,
                faults = g.faults,
                recovered = g.recovered,
                "the robot's state was not finite: the bridge was reset"
            );
        }
        if g.stale_state.episodes > was.stale_state.episodes {
            tracing::warn!(
                session = s.session,
                episodes = g.stale_state.episodes,
                "no robot state for longer than 50 ms: holding the last commanded pose, \
                 estimation paused until states return"
            );
        }
        if was.no_state_ticks == 0 && g.no_state_ticks > 0 {
            tracing::info!(
                "waiting for the robot's first state: nothing is commanded until it comes"
            );
        }
        self.logged = g;
        // Refusals are the node's (one per session): logged once per session.
        let refused = s.node.implausible_commands;
        if refused > 0 && (s.session != self.implausible_session || self.implausible == 0) {
            tracing::warn!(
                session = s.session,
                refused,
                "commands refused: implausible playout time (their clock jumped)"
            );
            self.implausible_session = s.session;
        }
        self.implausible = if s.session == self.implausible_session {
            refused
        } else {
            0
        };
    }
}

/// Gaps in the commands, seen from the loop's snapshots (20 ms resolution).
#[derive(Debug, Default)]
pub(crate) struct CommandGaps {
    /// `(session, commands)` of the last snapshot that showed a new command.
    last: (u64, u64),
    /// Its time \[ns\].
    at_ns: Option<i64>,
    pub(crate) outages: transport::Outages,
}

impl CommandGaps {
    pub(crate) fn update(&mut self, s: &LoopSnapshot) {
        let key = (s.session, s.node.commands);
        if key == self.last || s.node.commands == 0 {
            return;
        }
        if let Some(at) = self.at_ns
            && self.outages.record(s.now_ns - at)
        {
            tracing::warn!(
                session = s.session,
                gap_ms = (s.now_ns - at) / 1_000_000,
                outages = self.outages.count,
                "commands resumed after an outage"
            );
        }
        self.last = key;
        self.at_ns = Some(s.now_ns);
    }
}
