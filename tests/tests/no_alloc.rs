//! The two 1 kHz loops neither allocate nor free once running (`DESIGN.md` §2): the whole system
//! runs over loopback with a 100 ms shim while a counting global allocator (this test binary
//! only) counts the allocations and frees made on the threads named `haptic-loop` and
//! `telerobot-loop`. After a warm-up that covers the first contact, the first model and the
//! first clouds, the counts must not move — also while both sides record and serve the live
//! view (issue 15: the recording is written off the loops). The ROS 2 haptic device's loop side
//! (`--device ros2`) is checked the same way on a loop of its own.
#![allow(unsafe_code)] // the GlobalAlloc impl; see the SAFETY comments
#![allow(clippy::unwrap_used)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::Duration;

use testkit::daemons::*;
use testkit::*;

struct Counting;

/// Allocations and frees on the loop threads.
static ON_LOOPS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Whether this thread is a loop thread: unknown until its first allocation.
    static IS_LOOP: Cell<Option<bool>> = const { Cell::new(None) };
    /// Set while the allocator itself looks at the thread (no recursion).
    static BUSY: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    if BUSY.with(Cell::get) {
        return;
    }
    BUSY.with(|b| b.set(true));
    let is_loop = IS_LOOP.with(|l| match l.get() {
        Some(v) => v,
        None => {
            let v = matches!(
                std::thread::current().name(),
                Some("haptic-loop" | "telerobot-loop")
            );
            l.set(Some(v));
            v
        }
    });
    if is_loop {
        ON_LOOPS.fetch_add(1, Relaxed);
    }
    BUSY.with(|b| b.set(false));
}

// SAFETY: every call is forwarded unchanged to the system allocator; the bookkeeping uses
// const-initialised thread-locals and an atomic, and guards against re-entry.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller upholds `alloc`'s contract, which we pass on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count();
        // SAFETY: `ptr` was allocated by `System` with `layout` (all allocations go through it).
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: as for `dealloc`; the caller upholds `realloc`'s contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The loops' allocations and frees over the run's 4 s after a 5 s warm-up, from the session's
/// start on `tr`.
fn allocations_once_running(tr: &telerobot::Telerobot) -> u64 {
    wait_connected(tr);
    // Warm-up: contact at 1 s, the first model about 2 s later.
    std::thread::sleep(Duration::from_secs(5));
    let warm = ON_LOOPS.load(Relaxed);
    // The rest of the run: contact episodes end and start again, models and clouds keep coming.
    std::thread::sleep(Duration::from_secs(4));
    ON_LOOPS.load(Relaxed) - warm
}

#[test]
fn neither_loop_allocates_or_frees_once_running() {
    let _serial = serial();
    let (tr, shim, config) = through_shim(&Certs::new(), 100.0, 10.0);
    let operator = spawn_operator(config);
    let running = allocations_once_running(&tr);
    let outcome = operator.join().unwrap().unwrap();
    tr.stop();
    shim.shutdown().unwrap();
    assert!(outcome.report.experiment.render_start_s.is_some());
    assert_eq!(
        running, 0,
        "allocations or frees on the loop threads while running"
    );
}

/// Before: the recording branch of both loops (their tick records for `--record` and `--live`)
/// was allocation-free by reading only; no test ran the loops with a recorder.
#[test]
fn neither_loop_allocates_or_frees_while_both_sides_record() {
    let _serial = serial();
    let certs = Certs::new();
    let dir = std::env::temp_dir().join(format!("no-alloc-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let recorder = |name: &str, kind| {
        record::Recorder::start(record::RecorderConfig {
            mcap: Some(dir.join(name)),
            live: Some(([127, 0, 0, 1], 0).into()),
            kind,
            clock_origin_ns: rt::monotonic_ns(),
        })
        .unwrap()
    };
    let tr_recorder = recorder("telerobot.mcap", record::Kind::Telerobot);
    let op_recorder = recorder("operator.mcap", record::Kind::Operator);
    let (tr, shim, mut config) = through_shim_with(&certs, 100.0, 10.0, |c| {
        c.record = Some(tr_recorder.sink());
    });
    config.record = Some(op_recorder.sink());
    let operator = spawn_operator(config);
    let running = allocations_once_running(&tr);
    let outcome = operator.join().unwrap().unwrap();
    tr.stop();
    shim.shutdown().unwrap();
    let (tr_report, op_report) = (tr_recorder.finish().unwrap(), op_recorder.finish().unwrap());
    assert!(outcome.report.experiment.render_start_s.is_some());
    // Both recorded the run as it went.
    assert!(tr_report.messages > 10_000, "{tr_report:?}");
    assert!(op_report.messages > 10_000, "{op_report:?}");
    assert_eq!(
        running, 0,
        "allocations or frees on the loop threads while recording"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The ROS 2 device (`--device ros2`) against the forcedimension_ros2 double: reading the pose
/// and handing over the force, once a tick, allocate and free nothing on the loop's thread
/// (the DDS work, serialisation included, is on the device's I/O thread).
#[test]
fn the_ros2_devices_loop_side_neither_allocates_nor_frees() {
    use operator::device::ros::RosOptions;
    use operator::device::{DeviceSpec, ManagedConfig, OpenOptions, open_device};
    use ros2::fd_double::{FdDouble, Step, fd_pose};
    use ros2::haptic::{HapticConfig, HapticTopics};
    use std::time::Instant;

    let _serial = serial();
    let pid = std::process::id();
    let mut topics = HapticTopics::default();
    for (key, name) in [("pose", "ee_pose"), ("command", "fd_controller/commands")] {
        topics
            .remap(&format!("{key}=/no_alloc_{pid}/fd/{name}"))
            .unwrap();
    }
    let graph = ros2::GraphConfig {
        domain_id: 90 + (pid % 10) as u16,
        localhost_only: true,
    };
    let double = FdDouble::start(
        &ros2::Graph::join(&graph).unwrap(),
        &topics,
        1000.0,
        Box::new(|k, now| Step {
            pose: Some(fd_pose(now, [0.01 + 1e-6 * (k % 1000) as f64, 0.0, 0.0])),
            button: None,
        }),
    )
    .unwrap();
    let options = OpenOptions {
        managed: ManagedConfig {
            enable_ramp: Duration::ZERO,
            servo_watchdog: Duration::from_secs(10),
        },
        ros: RosOptions {
            graph: Some(graph),
            device: HapticConfig {
                topics,
                stale_after: Duration::from_secs(10),
                ..HapticConfig::default()
            },
            first_pose_timeout: Duration::from_secs(30),
        },
        ..OpenOptions::default()
    };
    let mut device = open_device(&DeviceSpec::Ros2, &options).unwrap();
    let loop_thread = std::thread::Builder::new()
        .name("haptic-loop".into())
        .spawn(move || {
            let start = Instant::now();
            device.enable(start.elapsed()).unwrap();
            let mut tick = |seconds: u64| {
                while start.elapsed() < Duration::from_secs(seconds) {
                    let now = start.elapsed();
                    device.update(now).unwrap();
                    device.servo_cf(now, [0.5, 0.0, 0.0]).unwrap();
                    std::thread::sleep(Duration::from_millis(1));
                }
            };
            tick(1);
            let warm = ON_LOOPS.load(Relaxed);
            tick(3);
            (ON_LOOPS.load(Relaxed) - warm, device)
        })
        .unwrap();
    let (running, device) = loop_thread.join().unwrap();
    let received = double.stop();
    assert!(
        received.iter().any(|c| c.message.data == [0.5, 0.0, 0.0]),
        "the forces reached the double"
    );
    drop(device);
    assert_eq!(
        running, 0,
        "allocations or frees on the device's loop thread"
    );
}
