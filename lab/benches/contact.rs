//! Criterion benches of the contact hot paths on the standard workload
//! (`sim::workload`): kd-tree build, proxy step on the kd-tree, the same step by brute
//! force. `mmt contact-bench` reports the same figures as medians and p99 in one run.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use mmt::contact::{CloudIndex, Neighbours, Proxy};
use sim::workload;

/// Steps along the workload's HIP path, one tick per iteration, wrapping around.
fn bench_steps<N: Neighbours>(c: &mut Criterion, name: &str, w: &workload::Workload, cloud: &N) {
    let mut proxy = Proxy::new(w.config, w.hips[0]).expect("default config is valid");
    let mut k = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            let out = proxy.step(w.hips[k], black_box(cloud));
            k = (k + 1) % w.hips.len();
            out
        })
    });
}

fn contact(c: &mut Criterion) {
    let mut build = c.benchmark_group("cloud_index_build");
    build.sample_size(10);
    for points in [10_000, 100_000, 307_200] {
        let w = workload::plane_sweep(points, 1, 0.0005, 1).expect("valid workload");
        build.bench_with_input(BenchmarkId::from_parameter(points), &w.frame, |b, frame| {
            b.iter(|| CloudIndex::build(black_box(frame)).expect("index builds"))
        });
    }
    build.finish();

    let w = workload::plane_sweep(307_200, 8_000, 0.0005, 1).expect("valid workload");
    let index = CloudIndex::build(&w.frame).expect("index builds");
    bench_steps(c, "proxy_step/kd_tree/307200", &w, &index);

    let small = workload::plane_sweep(10_000, 8_000, 0.0005, 1).expect("valid workload");
    let small_index = CloudIndex::build(&small.frame).expect("index builds");
    bench_steps(c, "proxy_step/kd_tree/10000", &small, &small_index);
    bench_steps(
        c,
        "proxy_step/brute_force/10000",
        &small,
        &small_index.brute_force(),
    );
}

criterion_group!(benches, contact);
criterion_main!(benches);
