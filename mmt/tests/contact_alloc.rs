//! Proxy steps allocate nothing (issue 3: "no per-step allocation"): once prepared for the
//! cloud, from the first step, whatever the HIP does; without `prepare`, once the neighbour
//! buffer has grown. A counting global allocator watches this thread only.

// A global allocator is the one way to observe allocations; the blocks below only forward to
// the system allocator.
#![allow(unsafe_code)]
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use mmt::cloud::Pose;
use mmt::contact::{CloudIndex, Neighbours, Proxy, ProxyConfig};
use rand::SeedableRng;
use sim::synthetic::{SceneObject, Shape, SyntheticCloud};
use sim::workload;

struct Counting;

thread_local! {
    // `const` initialisation without a destructor: using it never allocates.
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: every method forwards its arguments, under the same contract, to `System`.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract; passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: as for `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// One period of the workload's HIP path is 4 s (2 Hz in and out, 0.25 Hz around).
const PERIOD: usize = 4_000;

fn steady_state_allocations<N: Neighbours>(cloud: &N, w: &workload::Workload) -> u64 {
    let mut proxy = Proxy::new(w.config, w.hips[0]).unwrap();
    // Warm up over one period: the buffer grows to the largest neighbourhood of the path.
    for hip in &w.hips[..PERIOD] {
        proxy.step(*hip, cloud);
    }
    let before = allocations();
    let mut touching = 0;
    for hip in &w.hips[PERIOD..] {
        touching += usize::from(proxy.step(*hip, cloud).state.is_touching());
    }
    assert!(
        touching > PERIOD / 4,
        "the path must make contact: {touching}"
    );
    allocations() - before
}

#[test]
fn steady_state_steps_do_not_allocate() {
    let w = workload::plane_sweep(15_000, 2 * PERIOD, 0.0005, 11).unwrap();
    let index = CloudIndex::build(&w.frame).unwrap();
    assert_eq!(steady_state_allocations(&index, &w), 0, "kd-tree");
    assert_eq!(
        steady_state_allocations(&index.brute_force(), &w),
        0,
        "brute force"
    );
    // The counter does see allocations (the test can fail).
    let before = allocations();
    let v: Vec<u8> = Vec::with_capacity(64);
    drop(v);
    assert_eq!(allocations() - before, 1);
}

/// Straight HIP path from `from` to `to` at `speed` [m/s] and 1 kHz, `to` included.
fn line(from: [f64; 3], to: [f64; 3], speed: f64) -> Vec<[f64; 3]> {
    let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let ticks = (len / (speed * 1e-3)).ceil().max(1.0) as usize;
    (1..=ticks)
        .map(|k| {
            let s = k as f64 / ticks as f64;
            [from[0] + s * d[0], from[1] + s * d[1], from[2] + s * d[2]]
        })
        .collect()
}

/// `hold` ticks at `at`: a jump there when the HIP was elsewhere.
fn jump(at: [f64; 3], hold: usize) -> Vec<[f64; 3]> {
    vec![at; hold]
}

/// Steps a proxy prepared for `cloud` along `hips`, from its first step: the allocations, the
/// ticks touching, and the longest move of the proxy in one tick [m].
fn prepared_allocations<N: Neighbours>(cloud: &N, hips: &[[f64; 3]]) -> (u64, usize, f64) {
    let mut proxy = Proxy::new(ProxyConfig::default(), hips[0]).unwrap();
    proxy.prepare(cloud);
    let (mut touching, mut longest, mut last) = (0, 0.0f64, proxy.position());
    let before = allocations();
    for hip in hips {
        let out = proxy.step(*hip, cloud);
        touching += usize::from(out.state.is_touching());
        let d: f64 = (0..3).map(|i| (out.proxy_m[i] - last[i]).powi(2)).sum();
        longest = longest.max(d.sqrt());
        last = out.proxy_m;
    }
    (allocations() - before, touching, longest)
}

fn cloud(shape: Shape, spacing_m: f64, noise_std_m: f64) -> CloudIndex {
    let scene = SyntheticCloud {
        noise_std_m,
        ..SyntheticCloud::single(SceneObject::fixed(shape, Pose::IDENTITY), spacing_m)
    };
    let frame = scene
        .frame(0, &mut rand_pcg::Pcg64::seed_from_u64(5))
        .unwrap();
    CloudIndex::build(&frame).unwrap()
}

/// Regression: the buffer started at 1024 neighbours and grew with whatever a query returned,
/// so a 0.5 mm grid (~2,000 points in the 12 mm ball), a 5 cm HIP jump (a sweep ball of
/// |u|/2 + r3) or a small box inside the sweep's ball reallocated on the 1 kHz thread. No
/// warm-up here: the first step on a fresh, prepared proxy is counted.
#[test]
fn prepared_steps_do_not_allocate_on_a_fine_grid_long_jumps_or_a_small_box() {
    // A 0.5 mm grid plane at z = 0, 300 mm square (361,201 points), noisy: large enough that
    // the reservation is a bound from its density, not all of its points.
    let plane = cloud(
        Shape::Plane {
            size_x_m: 0.3,
            size_y_m: 0.3,
        },
        0.0005,
        0.0002,
    );
    let hips = [
        line([0.0, 0.0, 0.02], [0.0, 0.0, -0.003], 0.2),
        line([0.0, 0.0, -0.003], [0.02, 0.01, -0.003], 0.1),
        // 5 cm up in one tick, 5 cm sideways, 7 cm down through the plane, then a slide.
        jump([0.02, 0.01, 0.047], 5),
        jump([-0.03, 0.01, 0.047], 5),
        jump([-0.03, 0.01, -0.023], 20),
        line([-0.03, 0.01, -0.023], [0.0, -0.02, -0.003], 0.3),
        // 25 cm across the plane, just above it: one query for the whole sweep would hold
        // ~160,000 points.
        jump([-0.12, -0.1, 0.004], 5),
        jump([0.12, 0.1, 0.004], 20),
    ]
    .concat();
    for (name, result) in [
        ("kd-tree", prepared_allocations(&plane, &hips)),
        (
            "brute force",
            prepared_allocations(&plane.brute_force(), &hips),
        ),
    ] {
        let (allocated, touching, longest) = result;
        assert_eq!(allocated, 0, "0.5 mm grid, {name}");
        assert!(touching > 200, "{name}: the path must touch: {touching}");
        assert!(longest > 0.04, "{name}: the path must jump: {longest}");
    }

    // A 15 mm cube on a 0.5 mm grid: a sweep past it holds the whole box (~5,000 points); the
    // HIP jumps across it, through it and around its corner.
    let cube = cloud(Shape::Box { size_m: [0.015; 3] }, 0.0005, 0.0);
    let hips = [
        line([0.04, 0.0, 0.0], [0.03, 0.0, 0.0], 0.2),
        jump([-0.03, 0.0, 0.0], 10),
        jump([0.0, 0.0, 0.03], 5),
        jump([0.0, 0.0, 0.0], 10),
        jump([0.02, 0.02, 0.02], 5),
        line([0.02, 0.02, 0.02], [0.005, 0.005, 0.005], 0.2),
        jump([0.0, -0.03, 0.0], 10),
    ]
    .concat();
    let (allocated, touching, longest) = prepared_allocations(&cube, &hips);
    assert_eq!(allocated, 0, "15 mm cube");
    assert!(touching > 20 && longest > 0.02, "{touching} {longest}");
}
