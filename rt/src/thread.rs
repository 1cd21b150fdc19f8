//! Real-time threads: timer slack, `SCHED_FIFO` priority, and [`spawn`], which sets both.

use std::io;
use std::thread::JoinHandle;

/// Starts `body` on a new OS thread named `name`, with its timer slack at 1 ns (the default 50 µs
/// lets the kernel wake a sleeper that much late) and, with `priority = Some(p)`, under
/// `SCHED_FIFO` at `p` (needs `CAP_SYS_NICE`; refused → a warning, the loop runs anyway).
pub fn spawn<F, T>(name: &str, priority: Option<u8>, body: F) -> io::Result<JoinHandle<T>>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    let thread_name = name.to_owned();
    std::thread::Builder::new()
        .name(thread_name.clone())
        .spawn(move || {
            set_timer_slack_ns(1);
            if let Some(p) = priority
                && let Err(e) = set_realtime_priority(p)
            {
                tracing::warn!(thread = %thread_name, priority = p,
                    "SCHED_FIFO refused ({e}); running at normal priority");
            }
            body()
        })
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
pub fn set_realtime_priority(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: libc::c_int::from(priority),
    };
    // SAFETY: `param` is a valid, initialised `sched_param` that outlives the call; pid 0 means
    // the calling thread, so no other thread's state is touched.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Real-time scheduling is only implemented on Linux.
#[cfg(not(target_os = "linux"))]
pub fn set_realtime_priority(_priority: u8) -> io::Result<()> {
    Err(io::Error::from(io::ErrorKind::Unsupported))
}

/// Sets the calling thread's timer slack (no-op off Linux).
#[cfg(not(target_os = "linux"))]
pub fn set_timer_slack_ns(_slack_ns: u64) -> bool {
    false
}

/// A `--realtime-priority`: an integer from 1 to 99. `-1`, `0`, `100` and `high` get the same
/// message (issue 11: `-1` got clap's "invalid digit found in string").
pub fn parse_priority(s: &str) -> Result<u8, String> {
    s.trim()
        .parse::<i64>()
        .ok()
        .filter(|p| (1..=99).contains(p))
        .and_then(|p| u8::try_from(p).ok())
        .ok_or_else(|| "expected a SCHED_FIFO priority, an integer from 1 to 99".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spawned_thread_gets_its_slack_and_runs_without_priority() {
        let handle = spawn("test-loop", None, || set_timer_slack_ns(1)).unwrap();
        assert!(handle.join().unwrap() || !cfg!(target_os = "linux"));
    }

    #[test]
    fn a_priority_is_an_integer_from_1_to_99() {
        assert_eq!(parse_priority("1"), Ok(1));
        assert_eq!(parse_priority("99"), Ok(99));
        for bad in ["-1", "0", "100", "high", "", "1e3", "256"] {
            assert_eq!(
                parse_priority(bad),
                Err("expected a SCHED_FIFO priority, an integer from 1 to 99".to_owned()),
                "{bad}"
            );
        }
    }
}
