//! What the housekeeping thread watches in the loop's snapshots and tells: the motion guard's
//! work (once per episode: the loop only counts) and the gaps in the commands (outages across
//! sessions).

use record::schema::Level;

use crate::control::LoopSnapshot;

/// Logs the motion guard's work once per episode (the loop only counts).
#[derive(Debug, Default)]
pub(crate) struct GuardLog {
    logged: node::GuardStats,
    implausible: u64,
    implausible_session: u64,
}

impl GuardLog {
    /// Logs what the guard did since the last snapshot, and returns the same lines as events
    /// (for the recording's `/events`).
    pub(crate) fn update(&mut self, s: &LoopSnapshot) -> Vec<(Level, String)> {
        let mut events = Vec::new();
        let (g, was) = (s.guard, self.logged);
        let session = s.session;
        for (name, now, before) in [
            ("workspace box", g.workspace, was.workspace),
            ("largest step per tick", g.step, was.step),
            ("largest speed", g.speed, was.speed),
        ] {
            if now.episodes > before.episodes {
                tell(
                    &mut events,
                    Level::Warning,
                    format!(
                        "session {session}: the {name} limit clamped the commanded motion \
                         (episode {}, {} ticks so far)",
                        now.episodes, now.ticks
                    ),
                );
            }
        }
        if g.faults > was.faults {
            tell(
                &mut events,
                Level::Error,
                format!(
                    "session {session}: the robot's state was not finite: the bridge was reset \
                     ({} faults, {} recovered)",
                    g.faults, g.recovered
                ),
            );
        }
        if g.stale_state.episodes > was.stale_state.episodes {
            tell(
                &mut events,
                Level::Warning,
                format!(
                    "session {session}: no robot state for longer than 50 ms: holding the last \
                     commanded pose, estimation paused until states return (episode {})",
                    g.stale_state.episodes
                ),
            );
        }
        if was.no_state_ticks == 0 && g.no_state_ticks > 0 {
            tell(
                &mut events,
                Level::Info,
                "waiting for the robot's first state: nothing is commanded until it comes".into(),
            );
        }
        self.logged = g;
        self.refusals(s, &mut events);
        events
    }

    /// Refusals are the node's (one per session): logged once per session.
    fn refusals(&mut self, s: &LoopSnapshot, events: &mut Vec<(Level, String)>) {
        let refused = s.node.implausible_commands;
        if refused > 0 && (s.session != self.implausible_session || self.implausible == 0) {
            tell(
                events,
                Level::Warning,
                format!(
                    "session {}: {refused} commands refused: implausible playout time \
                     (their clock jumped)",
                    s.session
                ),
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

/// Logs `text` at `level` and keeps it as an event: one wording for the log and the recording.
fn tell(events: &mut Vec<(Level, String)>, level: Level, text: String) {
    match level {
        Level::Error => tracing::error!("{text}"),
        Level::Warning => tracing::warn!("{text}"),
        Level::Info => tracing::info!("{text}"),
    }
    events.push((level, text));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Before: the guard's work went to the log only; a recording (`/events`) had the session
    /// changes but no limit, fault or state gap of the telerobot.
    #[test]
    fn each_new_guard_episode_is_one_event_and_nothing_repeats() {
        let mut log = GuardLog::default();
        let mut s = LoopSnapshot {
            session: 3,
            ..LoopSnapshot::default()
        };
        assert!(log.update(&s).is_empty());
        s.guard.workspace.episodes = 1;
        s.guard.workspace.ticks = 40;
        s.guard.faults = 1;
        let events = log.update(&s);
        assert_eq!(events.len(), 2, "{events:?}");
        assert!(
            events
                .iter()
                .any(|(l, t)| *l == Level::Warning && t.contains("workspace box")),
            "{events:?}"
        );
        assert!(events.iter().any(|(l, _)| *l == Level::Error), "{events:?}");
        // The same counts again: nothing new.
        assert!(log.update(&s).is_empty());
        s.guard.stale_state.episodes = 1;
        let events = log.update(&s);
        assert_eq!(events.len(), 1, "{events:?}");
        assert!(events[0].1.contains("no robot state"), "{events:?}");
    }
}
