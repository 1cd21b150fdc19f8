//! The fuzz seeds of the `scene` target (`fuzz/seeds/scene/`), and the CI equivalent of that
//! target: arbitrary text and mutated seeds (values replaced by extreme numbers, lines dropped or
//! duplicated, bytes overwritten) are refused with an error naming the source, or accepted as a
//! scene every consumer takes: the settings, the simulated world, the written TOML. Never a
//! panic.
//!
//! `MMT_WRITE_FUZZ_SEEDS=1 cargo test -p sim --test fuzz_seeds` rewrites the seeds; without it
//! the test checks that the checked-in files are current.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use proptest::prelude::*;
use proptest::sample::Index;
use sim::scene::{EXP1_TOML, Scene, WALL_TOML};
use sim::world::World;

/// Every optional section and key: a file cloud with a pose, voxel grid and budget, the
/// `[limits]` and `[rates]` sections.
const EVERYTHING_TOML: &str = r#"name = "everything"
description = "every optional section: file cloud, limits, rates"

[environment]
mass_kg = 2.0
k_ground_n_per_m = 10.0
b_ground_ns_per_m = 30.0
k_contact_n_per_m = 800.0
b_contact_ns_per_m = 40.0
static_friction_n = 0.2
coulomb_friction_n = 0.1
stick_velocity_m_per_s = 0.004
anchored = false

[surface]
point_m = [0.01, -0.02, 0.03]
normal = [0.0, 0.6, 0.8]

[cloud]
source = "file"
path = "cloud.ply"
rate_hz = 10.0
moving = false
voxel_m = 0.002
max_points = 50000
pose = { translation_m = [0.1, 0.0, -0.1], quaternion_xyzw = [0.0, 0.0, 0.7071067811865476, 0.7071067811865476] }

[model]
normal = "kelvin-voigt"
tangential = "sliding-mass"
ground_spring = true
friction = false
filter_cutoff_hz = 8.0
forgetting = 0.999

[proxy]
r1_m = 0.003
r2_m = 0.005
r3_m = 0.02

[sensors]
preset = "clean"

[limits]
workspace_min_m = [-0.2, -0.3, -0.1]
workspace_max_m = [0.2, 0.3, 0.4]
max_step_m = 0.0005
max_speed_m_per_s = 0.5
max_clock_jump_s = 5.0

[rates]
control_hz = 500.0
"#;

/// A ROS 2 camera cloud with its topic and staleness.
fn ros2_toml() -> String {
    EXP1_TOML
        .replace(
            "[cloud]",
            "[cloud]\ntopic = \"/camera/depth/points\"\nstale_ms = 150.0\nvoxel_m = 0.005",
        )
        .replace("source = \"plane\"", "source = \"ros2\"")
}

/// The simulated camera with every fault a real one has: random dropout, hole patches and
/// depth noise, the band widened to hold it.
fn camera_toml() -> String {
    let text = EXP1_TOML
        .replacen(
            "dropout = 0.0",
            "dropout = 0.3\nholes = 0.2\nhole_radius_m = 0.02\n\
             depth_noise_per_m = 0.0037\ncamera_distance_m = 0.7",
            1,
        )
        .replacen("r2_m = 0.006", "r2_m = 0.008", 1);
    assert!(text.contains("holes = 0.2") && text.contains("r2_m = 0.008"));
    text
}

fn seeds() -> Vec<(&'static str, String)> {
    vec![
        ("exp1.toml", EXP1_TOML.to_owned()),
        ("camera.toml", camera_toml()),
        ("wall.toml", WALL_TOML.to_owned()),
        ("everything.toml", EVERYTHING_TOML.to_owned()),
        ("ros2.toml", ros2_toml()),
    ]
}

#[test]
fn every_seed_is_a_valid_scene_and_is_checked_in() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fuzz/seeds/scene");
    let write = std::env::var_os("MMT_WRITE_FUZZ_SEEDS").is_some();
    for (name, text) in seeds() {
        let scene = Scene::from_toml(&text, name).unwrap_or_else(|e| panic!("{e}"));
        consumers_accept(&scene).unwrap_or_else(|e| panic!("{name}: {e}"));
        let path = dir.join(name);
        if write {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, &text).unwrap();
        }
        let on_disk = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            on_disk == text,
            "{name} is stale: rerun with MMT_WRITE_FUZZ_SEEDS=1"
        );
    }
}

/// What the fuzz target checks of an accepted scene (less the node and the `Welcome`, which
/// are `node`'s and `protocol`'s): the limits validate, the world builds and gives finite samples
/// for a press into the surface, and the scene survives a write and re-parse.
fn consumers_accept(scene: &Scene) -> Result<(), String> {
    scene
        .telerobot_settings()
        .limits
        .validate()
        .map_err(|e| format!("limits: {e}"))?;
    let (n, p) = (scene.surface.normal, scene.surface.point_m);
    let at = |d: f64| [p[0] + d * n[0], p[1] + d * n[1], p[2] + d * n[2]];
    let mut world = World::new(scene, at(0.01), 7).map_err(|e| format!("world: {e}"))?;
    for k in 0..20 {
        let s = world.step(at(0.01 - 0.0006 * f64::from(k)), n.map(|c| -0.6 * c));
        if !(s.truth.is_finite() && s.measured.is_finite()) {
            return Err(format!("tick {k}: {s:?}"));
        }
    }
    let written = toml::to_string(scene).map_err(|e| format!("to_string: {e}"))?;
    let mut again = Scene::from_toml(&written, "again").map_err(|e| format!("again: {e}"))?;
    again.surface.normal = scene.surface.normal;
    if &again != scene {
        return Err(format!("written and read back differs:\n{written}"));
    }
    Ok(())
}

/// Values a mutation puts in place of a number: extremes, signs, non-numbers.
const VALUES: [&str; 16] = [
    "0",
    "-0.0",
    "1e308",
    "-1e308",
    "5e-324",
    "nan",
    "inf",
    "-inf",
    "1e-12",
    "-1",
    "9e18",
    "18446744073709551616",
    "\"x\"",
    "[]",
    "[1e308, 1e308, 1e308]",
    "true",
];

/// One edit of a scene's lines.
#[derive(Clone, Debug)]
enum Edit {
    /// Replace the value of the chosen `key = value` line.
    Value(Index, usize),
    /// Drop a line.
    Drop(Index),
    /// Duplicate a line.
    Duplicate(Index),
    /// Overwrite a byte of a line.
    Byte(Index, Index, u8),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => (any::<Index>(), 0..VALUES.len()).prop_map(|(i, v)| Edit::Value(i, v)),
        1 => any::<Index>().prop_map(Edit::Drop),
        1 => any::<Index>().prop_map(Edit::Duplicate),
        1 => (any::<Index>(), any::<Index>(), any::<u8>()).prop_map(|(l, b, v)| Edit::Byte(l, b, v)),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for e in edits {
        if lines.is_empty() {
            break;
        }
        match e {
            Edit::Value(i, v) => {
                let n = lines.len();
                let l = &mut lines[i.index(n)];
                if let Some((key, _)) = l.split_once('=') {
                    *l = format!("{key}= {}", VALUES[*v]);
                }
            }
            Edit::Drop(i) => {
                lines.remove(i.index(lines.len()));
            }
            Edit::Duplicate(i) => {
                let l = lines[i.index(lines.len())].clone();
                lines.push(l);
            }
            Edit::Byte(l, b, v) => {
                let n = lines.len();
                let line = &mut lines[l.index(n)];
                let mut bytes = std::mem::take(line).into_bytes();
                if !bytes.is_empty() {
                    let at = b.index(bytes.len());
                    bytes[at] = *v;
                }
                *line = String::from_utf8_lossy(&bytes).into_owned();
            }
        }
    }
    lines.join("\n")
}

fn check(text: &str) -> Result<(), TestCaseError> {
    match Scene::from_toml(text, "mutant.toml") {
        Ok(scene) => consumers_accept(&scene).map_err(TestCaseError::fail),
        Err(e) => {
            prop_assert!(e.to_string().starts_with("mutant.toml"), "{}", e);
            Ok(())
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn mutated_seeds_are_refused_or_usable(
        which in any::<Index>(),
        edits in prop::collection::vec(edit(), 1..6),
    ) {
        let all = seeds();
        let (_, seed) = &all[which.index(all.len())];
        check(&apply(seed, &edits))?;
    }

    #[test]
    fn arbitrary_text_is_refused_or_usable(text in "\\PC{0,200}") {
        check(&text)?;
    }
}
