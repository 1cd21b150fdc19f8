//! The one clock of the system, and the precise wait on it.
//!
//! [`monotonic_ns`] is `CLOCK_MONOTONIC` in nanoseconds as an `i64`: every daemon stamps its
//! messages with it, the real-time loops step their nodes with it, and the netem shim schedules
//! packets on it. Unlike `std::time::Instant` the value is a plain integer that can go on the
//! wire, and two processes on one host read the same clock, so one-way latency on loopback needs
//! no offset estimate (network notes §5.1).
//!
//! Precise waiting (network notes §0.2): sleep until `deadline − spin window`, then busy-spin.
//! Timers on this kernel wake 25–75 µs late; a 100–200 µs spin absorbs that, giving sub-µs
//! median lateness. Keep the spin short where cores are shared.

use std::time::Duration;

/// Default spin window \[ns\]: 200 µs, the short end that absorbed the timer's tail in the
/// measurements (network notes appendix A) without burning much of a shared core.
pub const DEFAULT_SPIN_WINDOW_NS: i64 = 200_000;

/// Nanoseconds of `CLOCK_MONOTONIC` (time since boot, not counting suspend). A vDSO call: no
/// system call, no lock, no allocation.
#[allow(unsafe_code)]
// `time_t` and `c_long` are i64 on 64-bit Linux but i32 on 32-bit targets.
#[allow(clippy::useless_conversion)]
pub fn monotonic_ns() -> i64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec for the duration of the call; CLOCK_MONOTONIC
    // is supported on every Linux, so the call cannot fail (and if it did, `ts` stays zeroed).
    unsafe {
        libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts);
    }
    i64::from(ts.tv_sec)
        .saturating_mul(1_000_000_000)
        .saturating_add(i64::from(ts.tv_nsec))
}

/// Waits until [`monotonic_ns`] ≥ `deadline_ns`: sleeps until `deadline_ns − spin_window_ns`
/// (each sleep computed from the absolute deadline, so lateness never accumulates), then spins.
/// Returns the time it woke.
pub fn sleep_until_ns(deadline_ns: i64, spin_window_ns: i64) -> i64 {
    sleep_until_on(monotonic_ns, deadline_ns, spin_window_ns)
}

/// [`sleep_until_ns`] on another monotonic nanosecond clock `now` (tests drive it with a fake
/// one).
pub fn sleep_until_on(now: impl Fn() -> i64, deadline_ns: i64, spin_window_ns: i64) -> i64 {
    let spin = spin_window_ns.max(0);
    loop {
        let now = now();
        if now >= deadline_ns {
            return now;
        }
        let remaining = deadline_ns.saturating_sub(now);
        if remaining > spin {
            let nanos = u64::try_from(remaining - spin).unwrap_or(0);
            std::thread::sleep(Duration::from_nanos(nanos));
        } else {
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_advances_like_instant() {
        let (a, t) = (monotonic_ns(), std::time::Instant::now());
        std::thread::sleep(Duration::from_millis(5));
        let (b, elapsed) = (monotonic_ns(), t.elapsed());
        let diff = b - a;
        let expected = i64::try_from(elapsed.as_nanos()).unwrap();
        assert!(a > 0 && diff >= 5_000_000, "{diff}");
        assert!((diff - expected).abs() < 1_000_000, "{diff} vs {expected}");
    }

    #[test]
    fn sleeps_until_the_deadline_not_before() {
        let deadline = monotonic_ns() + 2_000_000;
        let woke = sleep_until_ns(deadline, 100_000);
        assert!(woke >= deadline);
        assert!(monotonic_ns() >= woke);
    }

    #[test]
    fn a_deadline_in_the_past_returns_at_once() {
        let calls = std::cell::Cell::new(0);
        let woke = sleep_until_on(
            || {
                calls.set(calls.get() + 1);
                100
            },
            50,
            10,
        );
        assert_eq!((woke, calls.get()), (100, 1));
    }
}
