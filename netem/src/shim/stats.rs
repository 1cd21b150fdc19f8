//! The shim's counters, as a snapshot and as the table printed on exit.

use std::fmt;
use std::sync::atomic::Ordering::Relaxed;

use super::{Direction, Shared, lock};
use crate::model::LinkCounters;
use rt::{Histogram, Summary};

/// Counters of one direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DirectionStats {
    /// Datagrams received.
    pub received: u64,
    /// Copies sent on (duplicates included).
    pub forwarded: u64,
    /// Received datagrams of which the loss model let no copy through.
    pub dropped_loss: u64,
    /// Received datagrams dropped because the queue was full.
    pub dropped_limit: u64,
    /// Extra copies made by the duplicate option.
    pub duplicated: u64,
    /// Copies sent at once by the reorder option.
    pub reordered: u64,
    /// Copies released after a copy of a later arrival (reorder option or free-order jitter).
    pub out_of_order: u64,
    /// Copies whose send call failed.
    pub send_errors: u64,
    /// Release lateness: actual send time minus due time.
    pub lateness: Summary,
    /// The link model's own totals.
    pub link: LinkCounters,
}

/// Counters of the whole shim.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShimStats {
    /// Client → forward.
    pub up: DirectionStats,
    /// Forward → client.
    pub down: DirectionStats,
    /// Release lateness of both directions together.
    pub lateness: Summary,
    /// Down copies dropped because no client had sent yet.
    pub no_client: u64,
    /// Receive errors (e.g. ICMP port unreachable from `--forward`).
    pub recv_errors: u64,
    /// Times the client address changed.
    pub client_changes: u64,
    /// Copies still queued at shutdown (not sent).
    pub discarded_at_shutdown: u64,
    /// Log records lost because the writer fell behind.
    pub log_records_dropped: u64,
    /// Why the log writer stopped, if it failed.
    pub log_error: Option<String>,
    /// Why the scheduler's real-time priority was refused, if it was asked for and refused.
    pub realtime_error: Option<String>,
}

impl ShimStats {
    /// The counters of one direction.
    pub fn direction(&self, direction: Direction) -> &DirectionStats {
        match direction {
            Direction::Up => &self.up,
            Direction::Down => &self.down,
        }
    }
}

pub(super) fn snapshot(shared: &Shared) -> ShimStats {
    let direction = |d: Direction| {
        let i = d.index();
        let link = shared.link(d).counters();
        DirectionStats {
            received: link.offered,
            forwarded: shared.forwarded[i].load(Relaxed),
            dropped_loss: link.dropped_loss,
            dropped_limit: link.dropped_limit,
            duplicated: link.duplicated,
            reordered: link.reordered,
            out_of_order: shared.out_of_order[i].load(Relaxed),
            send_errors: shared.send_errors[i].load(Relaxed),
            lateness: shared.lateness[i].summary(),
            link,
        }
    };
    let [up_lateness, down_lateness] = &shared.lateness;
    ShimStats {
        up: direction(Direction::Up),
        down: direction(Direction::Down),
        lateness: Histogram::summary_of(&[up_lateness, down_lateness]),
        no_client: shared.no_client.load(Relaxed),
        recv_errors: shared.recv_errors.load(Relaxed),
        client_changes: shared.client_changes.load(Relaxed),
        discarded_at_shutdown: shared.discarded_at_shutdown.load(Relaxed),
        log_records_dropped: shared.log_records_dropped.load(Relaxed),
        log_error: lock(&shared.log_error).clone(),
        realtime_error: lock(&shared.realtime_error).clone(),
    }
}

impl fmt::Display for ShimStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:<5} {:>10} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
            "dir",
            "received",
            "forwarded",
            "lost",
            "limit",
            "dup",
            "reorder",
            "out-order",
            "send-err"
        )?;
        for (name, d) in [("up", &self.up), ("down", &self.down)] {
            writeln!(
                f,
                "{:<5} {:>10} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
                name,
                d.received,
                d.forwarded,
                d.dropped_loss,
                d.dropped_limit,
                d.duplicated,
                d.reordered,
                d.out_of_order,
                d.send_errors
            )?;
        }
        writeln!(f, "release lateness up:   {}", self.up.lateness)?;
        writeln!(f, "release lateness down: {}", self.down.lateness)?;
        write!(f, "release lateness all:  {}", self.lateness)?;
        let extras = [
            ("no client", self.no_client),
            ("receive errors", self.recv_errors),
            ("client changes", self.client_changes),
            ("discarded at shutdown", self.discarded_at_shutdown),
            ("log records dropped", self.log_records_dropped),
        ];
        for (label, value) in extras.iter().filter(|(_, v)| *v > 0) {
            write!(f, "\n{label}: {value}")?;
        }
        if let Some(error) = &self.log_error {
            write!(f, "\nlog write failed: {error}")?;
        }
        if let Some(error) = &self.realtime_error {
            write!(f, "\nreal-time priority refused: {error}")?;
        }
        Ok(())
    }
}
