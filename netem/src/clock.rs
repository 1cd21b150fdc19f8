//! The shim's clock and its precise waits.
//!
//! Time is nanoseconds since one process-wide [`Instant`] epoch (taken on first use), as a `u64`:
//! monotonic (CLOCK_MONOTONIC on Linux), cheap to read (vDSO), and the unit the link model takes.
//! In-process users (the operator's `demo`, tests) compare their own [`Instant`]s with the shim's
//! log through [`ns_since_epoch`]. Timestamps from another process are on another epoch.
//!
//! Precise waiting (network notes §0.2): sleep until `deadline − spin window`, then busy-spin.
//! Timers on this kernel wake 25–75 µs late; a 100–200 µs spin absorbs that, giving sub-µs median
//! lateness. Keep the spin short where cores are shared.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Default spin window [ns]: 200 µs, the short end that absorbed the timer's tail in the
/// measurements (network notes appendix A) without burning much of a shared core.
pub const DEFAULT_SPIN_WINDOW_NS: u64 = 200_000;

static EPOCH: OnceLock<Instant> = OnceLock::new();

/// The process-wide epoch (taken on first use).
pub fn epoch() -> Instant {
    *EPOCH.get_or_init(Instant::now)
}

/// Nanoseconds since [`epoch`].
pub fn now_ns() -> u64 {
    ns_since_epoch(Instant::now())
}

/// `t` as nanoseconds since [`epoch`] (0 for instants before it).
pub fn ns_since_epoch(t: Instant) -> u64 {
    u64::try_from(t.saturating_duration_since(epoch()).as_nanos()).unwrap_or(u64::MAX)
}

/// Waits until [`now_ns`] ≥ `deadline_ns`: sleeps until `deadline_ns − spin_window_ns` (each sleep
/// computed from the absolute deadline, so lateness never accumulates), then spins. Returns the
/// time it woke.
pub fn sleep_until_ns(deadline_ns: u64, spin_window_ns: u64) -> u64 {
    sleep_until_on(now_ns, deadline_ns, spin_window_ns)
}

/// [`sleep_until_ns`] on another monotonic nanosecond clock `now` (e.g. the daemons'
/// `CLOCK_MONOTONIC` without this module's epoch).
pub fn sleep_until_on(now: impl Fn() -> u64, deadline_ns: u64, spin_window_ns: u64) -> u64 {
    loop {
        let now = now();
        if now >= deadline_ns {
            return now;
        }
        let remaining = deadline_ns - now;
        if remaining > spin_window_ns {
            std::thread::sleep(Duration::from_nanos(remaining - spin_window_ns));
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Sets the calling thread's timer slack to `slack_ns` (Linux `PR_SET_TIMERSLACK`; the default
/// 50 µs slack lets the kernel wake a sleeper that much late). Returns whether it took effect;
/// always `false` off Linux.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn set_timer_slack_ns(slack_ns: u64) -> bool {
    let slack = libc::c_ulong::try_from(slack_ns).unwrap_or(libc::c_ulong::MAX);
    // SAFETY: PR_SET_TIMERSLACK takes one integer argument (the remaining ones are unused and
    // passed as 0); it reads and writes no memory of ours and changes only this thread's slack.
    let rc = unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, slack, 0, 0, 0) };
    rc == 0
}

/// Puts the calling thread under `SCHED_FIFO` at `priority` (1..=99), so that a runnable
/// real-time loop preempts ordinary work at once instead of waiting for a CFS time slice. Needs
/// `CAP_SYS_NICE` (or an `RLIMIT_RTPRIO` allowance); the kernel's RT throttling (by default 95 %
/// of each second) still leaves the rest of the machine some CPU.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn set_realtime_priority(priority: u8) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is a valid, initialised `sched_param` that outlives the call; pid 0 means
    // the calling thread, so no other thread's state is touched.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Real-time scheduling is only implemented on Linux.
#[cfg(not(target_os = "linux"))]
pub fn set_realtime_priority(_priority: u8) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}

/// Sets the calling thread's timer slack (no-op off Linux).
#[cfg(not(target_os = "linux"))]
pub fn set_timer_slack_ns(_slack_ns: u64) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sleeps_until_the_deadline_not_before() {
        let deadline = now_ns() + 2_000_000;
        let woke = sleep_until_ns(deadline, 100_000);
        assert!(woke >= deadline);
        assert!(now_ns() >= woke);
        assert!(set_timer_slack_ns(1) || !cfg!(target_os = "linux"));
    }
}
