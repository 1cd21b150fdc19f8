//! Model tests against exact answers (or, for random draws with a fixed seed, against bounds
//! derived from the distribution).

use super::*;

const MS: u64 = 1_000_000;

fn due_times(link: &mut Link, n: u64, spacing_ns: u64, len: usize) -> Vec<u64> {
    (0..n)
        .flat_map(|i| link.offer(i * spacing_ns, len).copies().collect::<Vec<_>>())
        .map(|d| d.due_ns)
        .collect()
}

/// |count − n·p| within `sigmas` binomial standard deviations.
fn assert_binomial(count: u64, n: u64, p: f64, sigmas: f64) {
    let mean = n as f64 * p;
    let sd = (n as f64 * p * (1.0 - p)).sqrt();
    assert!(
        (count as f64 - mean).abs() <= sigmas * sd,
        "{count} of {n}, expected {mean} ± {}",
        sigmas * sd
    );
}

#[test]
fn fixed_delay_is_exact() {
    let mut link = Link::new(LinkConfig::delay(400 * MS + 7), 1).unwrap();
    for i in 0..1000u64 {
        let now = i * 1_000_000 + i % 3;
        let fate = link.offer(now, 64);
        assert_eq!(
            fate,
            Fate::Delivered {
                original: Delivery {
                    due_ns: now + 400 * MS + 7,
                    reordered: false
                },
                duplicate: None
            }
        );
    }
}

#[test]
fn uniform_jitter_has_the_uniform_mean_variance_and_bounds() {
    let (delay, jitter) = (10 * MS, 2 * MS);
    let config = LinkConfig {
        delay_ns: delay,
        jitter_ns: jitter,
        keep_order: false,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 42).unwrap();
    let n = 200_000u64;
    let delays: Vec<f64> = (0..n)
        .map(|i| {
            let now = i * MS;
            let due = link.offer(now, 64).copies().next().unwrap().due_ns;
            assert!((delay - jitter..delay + jitter).contains(&(due - now)));
            (due - now) as f64
        })
        .collect();
    let mean = delays.iter().sum::<f64>() / n as f64;
    let var = delays.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n as f64;
    // Uniform on [μ−σ, μ+σ): mean μ − ½ ns, variance σ²/3; the mean's sd is σ/√(3n).
    let sigma = jitter as f64;
    let mean_sd = sigma / (3.0 * n as f64).sqrt();
    assert!((mean - delay as f64).abs() < 4.0 * mean_sd, "mean {mean}");
    // The variance estimate's relative sd is √(0.8/n) for a uniform (excess kurtosis −1.2).
    assert!(
        (var / (sigma * sigma / 3.0) - 1.0).abs() < 4.0 * (0.8 / n as f64).sqrt(),
        "variance {var}"
    );
}

#[test]
fn normal_jitter_has_sigma_equal_to_jitter() {
    let config = LinkConfig {
        delay_ns: 50 * MS,
        jitter_ns: 5 * MS,
        distribution: Distribution::Normal,
        keep_order: false,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 5).unwrap();
    let n = 100_000u64;
    let delays: Vec<f64> = (0..n)
        .map(|i| (link.offer(i * MS, 64).copies().next().unwrap().due_ns - i * MS) as f64)
        .collect();
    let mean = delays.iter().sum::<f64>() / n as f64;
    let sd = (delays.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    assert!(
        (mean / (50.0 * MS as f64) - 1.0).abs() < 0.002,
        "mean {mean}"
    );
    assert!((sd / (5.0 * MS as f64) - 1.0).abs() < 0.02, "sd {sd}");
}

#[test]
fn order_is_kept_by_default_and_free_order_reorders() {
    let jittery = LinkConfig {
        delay_ns: 20 * MS,
        jitter_ns: 5 * MS,
        ..LinkConfig::default()
    };
    let mut kept = Link::new(jittery.clone(), 9).unwrap();
    let dues = due_times(&mut kept, 5_000, MS, 64);
    assert!(dues.windows(2).all(|w| w[0] <= w[1]));
    // The running max raises the delay: never below the drawn delay's floor.
    assert!(
        dues.iter()
            .enumerate()
            .all(|(i, &d)| d >= i as u64 * MS + 15 * MS)
    );

    let mut free = Link::new(
        LinkConfig {
            keep_order: false,
            ..jittery
        },
        9,
    )
    .unwrap();
    let dues = due_times(&mut free, 5_000, MS, 64);
    let inversions = dues.windows(2).filter(|w| w[0] > w[1]).count();
    assert!(inversions > 1_000, "{inversions} inversions");
}

#[test]
fn bernoulli_loss_rate_is_within_the_binomial_bound() {
    let config = LinkConfig {
        loss: Loss::Random { probability: 0.05 },
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 1234).unwrap();
    let n = 100_000u64;
    for i in 0..n {
        link.offer(i, 100);
    }
    let c = link.counters();
    assert_binomial(c.dropped_loss, n, 0.05, 4.0);
    assert_eq!(c.delivered + c.dropped_loss, n);
}

#[test]
fn gilbert_elliott_link_matches_the_stationary_rate() {
    let loss = Loss::GilbertElliott {
        p: 0.05,
        r: 0.5,
        one_minus_h: 0.9,
        one_minus_k: 0.01,
    };
    let mut link = Link::new(
        LinkConfig {
            loss,
            ..LinkConfig::default()
        },
        77,
    )
    .unwrap();
    let n = 1_000_000u64;
    for i in 0..n {
        link.offer(i, 100);
    }
    let rate = link.counters().dropped_loss as f64 / n as f64;
    assert!(
        (rate / loss.mean_rate() - 1.0).abs() < 0.03,
        "{rate} vs {}",
        loss.mean_rate()
    );
}

#[test]
fn duplicate_rate_is_within_the_binomial_bound() {
    let config = LinkConfig {
        delay_ns: MS,
        duplicate_probability: 0.1,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 8).unwrap();
    let n = 100_000u64;
    let mut copies = 0u64;
    for i in 0..n {
        let fate = link.offer(i * MS, 100);
        copies += fate.copies().count() as u64;
    }
    let c = link.counters();
    assert_binomial(c.duplicated, n, 0.1, 4.0);
    assert_eq!(copies, n + c.duplicated);
    assert_eq!(c.delivered, copies);
}

#[test]
fn reorder_with_gap_sends_every_gap_th_packet_at_once() {
    let config = LinkConfig {
        delay_ns: 10 * MS,
        reorder_probability: 1.0,
        reorder_gap: 5,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 3).unwrap();
    for i in 0..50u64 {
        let now = i * MS;
        let d = link.offer(now, 64).copies().next().unwrap();
        if i % 5 == 4 {
            assert_eq!(
                d,
                Delivery {
                    due_ns: now,
                    reordered: true
                },
                "packet {i}"
            );
        } else {
            assert_eq!(d.due_ns, now + 10 * MS, "packet {i}");
        }
    }
    assert_eq!(link.counters().reordered, 10);
}

#[test]
fn reorder_probability_with_gap_one_applies_to_each_packet() {
    let config = LinkConfig {
        delay_ns: 10 * MS,
        reorder_probability: 0.25,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 4).unwrap();
    let n = 40_000u64;
    for i in 0..n {
        link.offer(i * MS, 64);
    }
    assert_binomial(link.counters().reordered, n, 0.25, 4.0);
}

#[test]
fn rate_serialises_from_the_last_due_time() {
    // 125 B at 1 Mbit/s = 1 ms on the wire; no overhead.
    let config = LinkConfig {
        delay_ns: 5 * MS,
        rate_bit_per_s: Some(1_000_000),
        overhead_bytes: 0,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 0).unwrap();
    // A burst at t = 0 queues behind itself: 5 ms + 1, 2, 3 … ms.
    let burst = due_times(&mut link, 1, 0, 125);
    assert_eq!(burst, vec![6 * MS]);
    for k in 2..=10u64 {
        assert_eq!(
            link.offer(0, 125).copies().next().unwrap().due_ns,
            (5 + k) * MS
        );
    }
    // After the queue drains, a packet waits only for its own delay and wire time.
    assert_eq!(
        link.offer(100 * MS, 125).copies().next().unwrap().due_ns,
        106 * MS
    );
    // Overhead counts: 97 B + 28 B = 125 B.
    let mut link = Link::new(
        LinkConfig {
            rate_bit_per_s: Some(1_000_000),
            ..LinkConfig::default()
        },
        0,
    )
    .unwrap();
    assert_eq!(link.offer(0, 97).copies().next().unwrap().due_ns, MS);
    // 10 Mbit/s, 1000 B + 28 B = 8224 bits → 822 400 ns, floor division as netem.
    let mut link = Link::new(
        LinkConfig {
            rate_bit_per_s: Some(10_000_000),
            ..LinkConfig::default()
        },
        0,
    )
    .unwrap();
    assert_eq!(link.offer(0, 1000).copies().next().unwrap().due_ns, 822_400);
}

#[test]
fn limit_drops_are_counted_and_the_queue_drains() {
    let config = LinkConfig {
        delay_ns: 1_000 * MS,
        limit_packets: 10,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 0).unwrap();
    let fates: Vec<Fate> = (0..15u64).map(|i| link.offer(i, 64)).collect();
    assert!(
        fates[..10]
            .iter()
            .all(|f| matches!(f, Fate::Delivered { .. }))
    );
    assert!(
        fates[10..]
            .iter()
            .all(|f| *f == Fate::Dropped(DropReason::Limit))
    );
    assert_eq!(link.in_flight(9), 10);
    // Once the first packets are due, there is room again.
    assert_eq!(link.in_flight(1_000 * MS + 1), 8);
    assert!(matches!(
        link.offer(1_000 * MS + 1, 64),
        Fate::Delivered { .. }
    ));
    let c = link.counters();
    assert_eq!((c.offered, c.delivered, c.dropped_limit), (16, 11, 5));
}

fn everything() -> LinkConfig {
    LinkConfig {
        delay_ns: 20 * MS,
        jitter_ns: 3 * MS,
        jitter_correlation: 0.25,
        distribution: Distribution::ParetoNormal,
        loss: Loss::GilbertElliott {
            p: 0.02,
            r: 0.4,
            one_minus_h: 0.9,
            one_minus_k: 0.01,
        },
        duplicate_probability: 0.03,
        reorder_probability: 0.05,
        reorder_gap: 3,
        rate_bit_per_s: Some(50_000_000),
        limit_packets: 50,
        keep_order: false,
        ..LinkConfig::default()
    }
}

#[test]
fn same_seed_gives_the_same_fates() {
    let run = |seed| {
        let mut link = Link::new(everything(), seed).unwrap();
        let fates: Vec<Fate> = (0..20_000u64)
            .map(|i| link.offer(i * 100_000, 64 + (i % 1200) as usize))
            .collect();
        (fates, link.counters())
    };
    let (a, ca) = run(99);
    let (b, cb) = run(99);
    let (c, _) = run(100);
    assert_eq!(a, b);
    assert_eq!(ca, cb);
    assert_ne!(a, c);
    // Every impairment was exercised, and the counters add up.
    assert!(ca.dropped_loss > 0 && ca.dropped_limit > 0 && ca.duplicated > 0 && ca.reordered > 0);
    assert_eq!(
        ca.offered,
        ca.delivered - ca.duplicated + ca.dropped_loss + ca.dropped_limit
    );
}

#[test]
fn reconfiguration_gives_an_outage_and_recovers() {
    let mut link = Link::new(LinkConfig::delay(10 * MS), 0).unwrap();
    assert!(matches!(link.offer(0, 64), Fate::Delivered { .. }));
    let down = LinkConfig {
        loss: Loss::Random { probability: 1.0 },
        ..LinkConfig::delay(10 * MS)
    };
    link.set_config(down).unwrap();
    assert!((1..1000u64).all(|i| link.offer(i * MS, 64) == Fate::Dropped(DropReason::Loss)));
    link.set_config(LinkConfig::delay(MS)).unwrap();
    let due = link.offer(1000 * MS, 64).copies().next().unwrap().due_ns;
    assert_eq!(due, 1001 * MS);
    assert_eq!(link.counters().dropped_loss, 999);
    // Order kept across a change: a packet after the delay drops may not overtake one before.
    link.set_config(LinkConfig::delay(400 * MS)).unwrap();
    assert_eq!(
        link.offer(2000 * MS, 64).copies().next().unwrap().due_ns,
        2400 * MS
    );
    link.set_config(LinkConfig::delay(MS)).unwrap();
    assert_eq!(
        link.offer(2001 * MS, 64).copies().next().unwrap().due_ns,
        2400 * MS
    );
    // An invalid change is refused and leaves the link as it was.
    let bad = LinkConfig {
        jitter_ns: u64::MAX,
        ..LinkConfig::default()
    };
    assert_eq!(link.set_config(bad).unwrap_err().field, "jitter_ns");
    assert_eq!(link.config(), &LinkConfig::delay(MS));
}

#[test]
fn time_going_backwards_or_extreme_values_do_not_panic() {
    let config = LinkConfig {
        delay_ns: config::MAX_DELAY_NS,
        jitter_ns: config::MAX_JITTER_NS,
        rate_bit_per_s: Some(1),
        overhead_bytes: -65_535,
        ..LinkConfig::default()
    };
    let mut link = Link::new(config, 0).unwrap();
    for now in [u64::MAX, 5, 0, u64::MAX - 1] {
        for len in [0, 1, 65_535, usize::MAX] {
            for copy in link.offer(now, len).copies() {
                assert!(copy.due_ns >= now);
            }
        }
    }
}
