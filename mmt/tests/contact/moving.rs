//! Clouds that change between steps: a plane sliding into a static HIP (the operator's delayed
//! copy and the telerobot's live cloud both change under a resting tool), frames at camera rate.

use mmt::contact::{CloudIndex, ContactState, Proxy};

use crate::support::*;

/// Steps a proxy at a static HIP while the plane slides toward it along its normal; one cloud
/// frame every `frame_ticks` ticks (1 = a new frame per 1 kHz tick, 33 ≈ a 30 Hz camera).
/// Returns the outputs and the plane's origin at each tick.
fn approach(
    speed: f64,
    frame_ticks: usize,
    ticks: usize,
) -> (Vec<mmt::contact::ContactOutput>, Vec<[f64; 3]>) {
    let n = unit([0.1, 0.2, 1.0]);
    let start = scale(n, -0.01);
    let object = sliding(plane(n, start, 0.06), scale(n, speed));
    let sensor = Sensor::noisy(0.0002);
    let hip = [0.0; 3];
    let mut proxy = Proxy::new(config(), hip).unwrap();
    let mut index: Option<CloudIndex> = None;
    let mut out = Vec::new();
    let mut origins = Vec::new();
    for k in 0..ticks {
        if k % frame_ticks == 0 {
            let t_ns = (k as i64) * 1_000_000;
            index = Some(CloudIndex::build(&frame(&object, &sensor, t_ns)).unwrap());
        }
        let frame_tick = k - k % frame_ticks;
        origins.push(object.pose_at(frame_tick as f64 / RATE_HZ).translation_m);
        out.push(proxy.step(hip, index.as_ref().unwrap()));
    }
    (out, origins)
}

#[test]
fn a_moving_plane_approaching_a_static_hip_registers_contact() {
    let c = config();
    let n = unit([0.1, 0.2, 1.0]);
    for (speed, frame_ticks) in [(0.05, 1), (0.2, 1), (0.5, 1), (0.03, 33)] {
        // From 10 mm below the HIP to 10 mm past it.
        let ticks = (0.02 / speed * RATE_HZ) as usize;
        let (out, origins) = approach(speed, frame_ticks, ticks);
        let height = |k: usize, p: [f64; 3]| dot(sub(p, origins[k]), n);
        // Contact is registered no later than one frame after the plane is within r2 of the
        // HIP (the surface the proxy sees moves only when a frame arrives).
        let reached = (0..ticks)
            .position(|k| height(k, [0.0; 3]) <= c.r2_m)
            .unwrap();
        let contact = out.iter().position(|o| o.state.is_touching()).unwrap();
        assert!(
            contact <= reached + frame_ticks,
            "{speed} m/s: {contact} vs {reached}"
        );
        for (k, o) in out.iter().enumerate() {
            assert_finite(o);
            // Never left behind: the proxy stays on the near side of the moving plane.
            assert!(height(k, o.proxy_m) > 0.0, "{speed} m/s, tick {k}: {o:?}");
        }
        // Once the plane is past the HIP the proxy is pushed: in contact, the HIP "inside",
        // the penetration about the plane's travel past the HIP plus the rest distance.
        let last = out.last().unwrap();
        assert!(last.state.is_touching(), "{speed} m/s: {last:?}");
        let past = -height(ticks - 1, [0.0; 3]);
        let pen = last.penetration_m.unwrap();
        assert!(
            pen > past && pen < past + c.r2_m + 0.001,
            "{speed} m/s: {pen} vs {past}"
        );
    }
}

#[test]
fn the_velocity_term_tracks_a_cloud_pushing_the_proxy() {
    // At 1 kHz frames the proxy is pushed every tick; eq. 12 makes v̂ the push speed, and the
    // step then starts by moving ahead of the plane, so it is rarely entrenched.
    let speed = 0.2;
    let ticks = (0.02 / speed * RATE_HZ) as usize;
    let (out, _) = approach(speed, 1, ticks);
    let pushed = &out[ticks / 2..];
    assert!(pushed.iter().all(|o| o.state.is_touching()));
    let entrenched = pushed
        .iter()
        .filter(|o| o.step_state == ContactState::Entrenched)
        .count();
    assert!(
        entrenched * 10 < pushed.len(),
        "{entrenched} of {}",
        pushed.len()
    );
}

#[test]
fn two_clouds_alternating_between_steps_are_each_respected() {
    // The operator steps on its delayed copy; a new copy may arrive at any tick. Alternate two
    // different frames of a plane 1 mm apart: the proxy must follow whichever it is given.
    let c = config();
    let n = [0.0, 0.0, 1.0];
    let sensor = Sensor::noisy(0.0);
    let a = index(&plane(n, [0.0; 3], 0.05), &sensor);
    let b = index(&plane(n, [0.0, 0.0, 0.001], 0.05), &sensor);
    let hip = [0.0, 0.0, -0.004];
    let mut proxy = Proxy::new(c, [0.0, 0.0, 0.02]).unwrap();
    for k in 0..200 {
        let cloud = if k % 2 == 0 { &a } else { &b };
        let o = proxy.step(hip, cloud);
        let floor = if k % 2 == 0 { 0.0 } else { 0.001 };
        assert!(o.proxy_m[2] > floor, "tick {k}: {o:?}");
        if k > 100 {
            assert!(
                o.state.is_touching() && o.proxy_m[2] < floor + c.r2_m,
                "tick {k}: {o:?}"
            );
        }
    }
}
