//! The one clock of both daemons: `CLOCK_MONOTONIC` in nanoseconds.
//!
//! Receipt stamps, `Ping`/`Pong` times and header send times are read here, so the real-time
//! loops must read the same clock for their `now` (and for `sample_time_ns`). Unlike
//! `std::time::Instant` the value is a plain integer that can go on the wire, and two processes
//! on one host read the same clock, so one-way latency on loopback needs no offset estimate
//! (network notes §5.1).

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_advances_like_instant() {
        let (a, t) = (monotonic_ns(), std::time::Instant::now());
        std::thread::sleep(std::time::Duration::from_millis(5));
        let (b, elapsed) = (monotonic_ns(), t.elapsed());
        let diff = b - a;
        let expected = i64::try_from(elapsed.as_nanos()).unwrap();
        assert!(a > 0 && diff >= 5_000_000, "{diff}");
        assert!((diff - expected).abs() < 1_000_000, "{diff} vs {expected}");
    }
}
