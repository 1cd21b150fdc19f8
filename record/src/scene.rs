//! The 3-D scene at display rate, from the latest recorded state: the table and the object (when
//! the scene is known; the object slides as the robot bridge says, and is drawn under the tool
//! where each contact begins: the simulated object has no edges, so the drawn box is the part of
//! it being touched, not its outline), the proxy sphere coloured by the contact state (green
//! free, orange contact, red entrenched), the device's point, the force arrow and the surface
//! frame's axes (`foxglove.SceneUpdate` on `/scene`, and `foxglove.FrameTransform` `world` →
//! `surface` on `/tf`).
//!
//! The view is the operator's where the recording has an operator side (what the operator
//! renders, on the cloud it received), the telerobot's otherwise (the measured tool and force).

use foxglove::messages::{
    ArrowPrimitive, Color, CubePrimitive, FrameTransform, Pose, Quaternion, SceneEntity,
    SceneUpdate, SpherePrimitive, Vector3,
};
use mmt::vec3::{self, Vec3};

use crate::encode::timestamp;
use crate::schema::{ContactStateRec, FrameRec, Message, Side};

/// Scenes per second (the display rate; at most 60).
pub const SCENE_RATE_HZ: f64 = 50.0;
/// Force arrow length per newton \[m/N\].
const ARROW_M_PER_N: f64 = 0.02;
/// The drawn object: width and depth along the tangents, height along the normal \[m\].
const OBJECT_SIZE_M: [f64; 3] = [0.2, 0.2, 0.05];
/// The drawn table: width and depth \[m\] and thickness \[m\].
const TABLE_SIZE_M: [f64; 3] = [0.6, 0.6, 0.02];

/// What the scene shows, kept up to date from the recorded messages.
#[derive(Debug, Default)]
pub struct SceneState {
    surface: Option<(Vec3, FrameRec)>,
    proxy_radius_m: f64,
    has_operator: bool,
    /// Contact states come from the operator (what it received); the telerobot's count until
    /// one does (an experiment records only the telerobot's).
    operator_contacts: bool,
    point: Option<Vec3>,
    force: Vec3,
    proxy: Option<Vec3>,
    contact: Option<ContactStateRec>,
    frame: Option<(Vec3, FrameRec)>,
    slide: [f64; 2],
    /// Where the drawn object's centre is at zero slide, along the tangents from the surface
    /// point \[m\]: set under the tool when a contact begins.
    anchor: [f64; 2],
    /// The telerobot's contact flag at its last tick.
    touching: bool,
    next_ns: Option<i64>,
}

impl SceneState {
    /// Takes what the scene needs from `message` (at `t_ns`); returns whether a scene is due.
    pub fn update(&mut self, t_ns: i64, message: &Message) -> bool {
        let mut tick = false;
        match message {
            Message::Run(r) => {
                self.proxy_radius_m = r.proxy_radii_m[0];
                if let Some(scene) = &r.scene {
                    let n = scene.surface.normal;
                    let frame = mmt::contact::SurfaceFrame::from_normal(n).map(|f| FrameRec {
                        normal: f.normal,
                        tangent1: f.tangent1,
                        tangent2: f.tangent2,
                    });
                    if let Some(frame) = frame {
                        self.surface = Some((scene.surface.point_m, frame));
                    }
                }
            }
            Message::OperatorTick(t) => {
                self.has_operator = true;
                self.point = Some(t.command_position_m);
                self.force = t.force_device_n;
                self.proxy = t.proxy_m.or(self.proxy);
                tick = true;
            }
            Message::Contact(side, c) if *side == Side::Operator || !self.operator_contacts => {
                self.operator_contacts |= *side == Side::Operator;
                self.contact = Some(c.state);
                if !self.has_operator {
                    self.proxy = Some(c.proxy_position_m);
                }
                self.frame = c.frame.zip(c.surface_point_m).map(|(f, p)| (p, f));
            }
            Message::TelerobotTick(t) => {
                self.slide = t.object_slide_m;
                if t.in_contact && !self.touching {
                    self.anchor_under(t.position_m);
                }
                self.touching = t.in_contact;
                if !self.has_operator {
                    self.point = Some(t.position_m);
                    self.force = t.force_on_tool_n;
                    tick = true;
                }
            }
            _ => {}
        }
        if !tick {
            return false;
        }
        let period = (1e9 / SCENE_RATE_HZ) as i64;
        match self.next_ns {
            Some(next) if t_ns < next => false,
            _ => {
                self.next_ns = Some(t_ns + period);
                true
            }
        }
    }

    /// Puts the drawn object's centre under `tool_m` (along the tangents), at the slide now.
    fn anchor_under(&mut self, tool_m: Vec3) {
        if let Some((point, frame)) = &self.surface {
            let d = vec3::sub(tool_m, *point);
            self.anchor = [
                vec3::dot(d, frame.tangent1) - self.slide[0],
                vec3::dot(d, frame.tangent2) - self.slide[1],
            ];
        }
    }

    /// The table and the object on it, where the surface was last seen (none before).
    fn table_and_object(&self, entity: &dyn Fn(&str) -> SceneEntity) -> Vec<SceneEntity> {
        let Some((point, frame)) = self.surface else {
            return Vec::new();
        };
        let rotation = quaternion_of(&frame);
        let along = |d: [f64; 3]| {
            vec3::add(
                vec3::scale(frame.tangent1, d[0]),
                vec3::add(
                    vec3::scale(frame.tangent2, d[1]),
                    vec3::scale(frame.normal, d[2]),
                ),
            )
        };
        let [w, d, h] = OBJECT_SIZE_M;
        let object_centre = vec3::add(
            point,
            along([
                self.anchor[0] + self.slide[0],
                self.anchor[1] + self.slide[1],
                -h / 2.0,
            ]),
        );
        let table_centre = vec3::add(point, along([0.0, 0.0, -h - TABLE_SIZE_M[2] / 2.0]));
        let cube = |centre: Vec3, size: [f64; 3], color: Color| CubePrimitive {
            pose: Some(pose(centre, rotation)),
            size: Some(v3(size)),
            color: Some(color),
        };
        let mut table = entity("table");
        table
            .cubes
            .push(cube(table_centre, TABLE_SIZE_M, rgba(0.55, 0.5, 0.45, 1.0)));
        let mut object = entity("object");
        object
            .cubes
            .push(cube(object_centre, [w, d, h], rgba(0.9, 0.75, 0.3, 0.6)));
        vec![table, object]
    }

    /// The scene now, stamped `log_time_ns`.
    pub fn scene(&self, log_time_ns: u64) -> SceneUpdate {
        let stamp = Some(timestamp(log_time_ns));
        let entity = |id: &str| SceneEntity {
            timestamp: stamp,
            frame_id: "world".to_owned(),
            id: id.to_owned(),
            ..SceneEntity::default()
        };
        let mut entities = self.table_and_object(&entity);
        if let Some(p) = self.proxy {
            let mut proxy = entity("proxy");
            let color = match self.contact {
                Some(ContactStateRec::Contact) => rgba(1.0, 0.55, 0.0, 0.8),
                Some(ContactStateRec::Entrenched) => rgba(0.9, 0.1, 0.1, 0.8),
                _ => rgba(0.2, 0.8, 0.3, 0.8),
            };
            let r = self.proxy_radius_m.max(0.002);
            proxy.spheres.push(SpherePrimitive {
                pose: Some(pose(p, identity())),
                size: Some(v3([2.0 * r; 3])),
                color: Some(color),
            });
            entities.push(proxy);
        }
        if let Some(p) = self.point {
            let mut device = entity("device");
            device.spheres.push(SpherePrimitive {
                pose: Some(pose(p, identity())),
                size: Some(v3([0.004; 3])),
                color: Some(rgba(0.2, 0.4, 1.0, 1.0)),
            });
            let mut force = entity("force");
            if let Some(a) = arrow(p, self.force, ARROW_M_PER_N, rgba(0.9, 0.1, 0.8, 1.0)) {
                force.arrows.push(a);
            }
            entities.extend([device, force]);
        }
        let mut frame = entity("surface_frame");
        if let Some((p, f)) = self.frame {
            for (axis, color) in [
                (f.tangent1, rgba(1.0, 0.2, 0.2, 1.0)),
                (f.tangent2, rgba(0.2, 1.0, 0.2, 1.0)),
                (f.normal, rgba(0.2, 0.4, 1.0, 1.0)),
            ] {
                frame.arrows.extend(arrow(p, axis, 0.03, color));
            }
        }
        entities.push(frame);
        SceneUpdate {
            deletions: Vec::new(),
            entities,
        }
    }

    /// `world` → `surface` at the contact's surface point, when in contact.
    pub fn transform(&self, log_time_ns: u64) -> Option<FrameTransform> {
        let (p, f) = self.frame?;
        Some(FrameTransform {
            timestamp: Some(timestamp(log_time_ns)),
            parent_frame_id: "world".to_owned(),
            child_frame_id: "surface".to_owned(),
            translation: Some(v3(p)),
            rotation: Some(quaternion_of(&f)),
        })
    }
}

fn v3(v: [f64; 3]) -> Vector3 {
    Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    }
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

fn identity() -> Quaternion {
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 1.0,
    }
}

fn pose(position: Vec3, orientation: Quaternion) -> Pose {
    Pose {
        position: Some(v3(position)),
        orientation: Some(orientation),
    }
}

/// An arrow from `from` along `v`, `scale` metres per unit of `v` (Foxglove's arrows point along
/// their pose's +x); `None` for a vector too short to draw.
fn arrow(from: Vec3, v: Vec3, scale: f64, color: Color) -> Option<ArrowPrimitive> {
    let norm = vec3::norm2(v).sqrt();
    if !(norm * scale > 1e-4) {
        return None;
    }
    let length = norm * scale;
    let head = (0.25 * length).min(0.01);
    Some(ArrowPrimitive {
        pose: Some(pose(from, rotation_from_x(vec3::scale(v, 1.0 / norm)))),
        shaft_length: length - head,
        shaft_diameter: 0.002,
        head_length: head,
        head_diameter: 0.005,
        color: Some(color),
    })
}

/// The rotation taking +x onto the unit vector `d`.
fn rotation_from_x(d: Vec3) -> Quaternion {
    let x = [1.0, 0.0, 0.0];
    let c = vec3::dot(x, d);
    if c < -1.0 + 1e-9 {
        // Opposite: half a turn about z.
        return Quaternion {
            x: 0.0,
            y: 0.0,
            z: 1.0,
            w: 0.0,
        };
    }
    let axis = [0.0, -d[2], d[1]]; // x × d
    let w = 1.0 + c;
    let n = (w * w + vec3::norm2(axis)).sqrt();
    Quaternion {
        x: axis[0] / n,
        y: axis[1] / n,
        z: axis[2] / n,
        w: w / n,
    }
}

/// The rotation whose columns are `tangent1`, `tangent2`, `normal` (world ← surface).
fn quaternion_of(f: &FrameRec) -> Quaternion {
    let m = [
        [f.tangent1[0], f.tangent2[0], f.normal[0]],
        [f.tangent1[1], f.tangent2[1], f.normal[1]],
        [f.tangent1[2], f.tangent2[2], f.normal[2]],
    ];
    let trace = m[0][0] + m[1][1] + m[2][2];
    let (x, y, z, w) = if trace > 0.0 {
        let s = 2.0 * (1.0 + trace).sqrt();
        (
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
            0.25 * s,
        )
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
        (
            0.25 * s,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[2][1] - m[1][2]) / s,
        )
    } else if m[1][1] > m[2][2] {
        let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
        (
            (m[0][1] + m[1][0]) / s,
            0.25 * s,
            (m[1][2] + m[2][1]) / s,
            (m[0][2] - m[2][0]) / s,
        )
    } else {
        let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
        (
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            0.25 * s,
            (m[1][0] - m[0][1]) / s,
        )
    };
    Quaternion { x, y, z, w }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rotates `v` by `q`.
    fn rotate(q: &Quaternion, v: Vec3) -> Vec3 {
        let u = [q.x, q.y, q.z];
        let t = vec3::scale(cross(u, v), 2.0);
        vec3::add(v, vec3::add(vec3::scale(t, q.w), cross(u, t)))
    }

    fn cross(a: Vec3, b: Vec3) -> Vec3 {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12)
    }

    /// Before: the box was drawn at the surface point plus the slide since the start; the
    /// simulated object has no edges and each contact begins wherever the tool comes down, so
    /// after a few contacts the demo drew the tool 0.1 m off the box it was pushing.
    #[test]
    fn the_object_is_drawn_under_the_tool_where_a_contact_begins_and_slides_from_there() {
        let mut state = SceneState {
            surface: Some((
                [0.0, 0.0, 0.0],
                FrameRec {
                    normal: [0.0, 0.0, 1.0],
                    tangent1: [1.0, 0.0, 0.0],
                    tangent2: [0.0, 1.0, 0.0],
                },
            )),
            ..SceneState::default()
        };
        let mut tick = |position_m: Vec3, slide: [f64; 2], in_contact: bool| {
            let t = crate::schema::TelerobotTick {
                position_m,
                object_slide_m: slide,
                in_contact,
                ..Default::default()
            };
            state.update(0, &Message::TelerobotTick(Box::new(t)));
            let entities = state.table_and_object(&|id: &str| SceneEntity {
                id: id.to_owned(),
                ..SceneEntity::default()
            });
            let object = entities.iter().find(|e| e.id == "object").unwrap();
            let p = object.cubes[0]
                .pose
                .as_ref()
                .unwrap()
                .position
                .as_ref()
                .unwrap();
            [p.x, p.y, p.z]
        };
        // Free: the object where it slid to; a contact begins at y 0.05 with 0.1 m of slide.
        let free = tick([0.0, 0.05, 0.01], [0.0, -0.1], false);
        assert!(close(free, [0.0, -0.1, -0.025]), "{free:?}");
        let onset = tick([0.0, 0.05, -0.001], [0.0, -0.1], true);
        assert!(close(onset, [0.0, 0.05, -0.025]), "{onset:?}");
        // It slides with the object, whatever the tool does within the contact.
        let pushed = tick([0.03, 0.07, -0.002], [0.01, -0.08], true);
        assert!(close(pushed, [0.01, 0.07, -0.025]), "{pushed:?}");
        // Lifted and put down elsewhere: under the tool again.
        tick([0.03, 0.07, 0.01], [0.01, -0.08], false);
        let again = tick([-0.02, 0.0, -0.001], [0.01, -0.08], true);
        assert!(close(again, [-0.02, 0.0, -0.025]), "{again:?}");
    }

    #[test]
    fn arrows_point_along_their_vector() {
        for d in [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.6, -0.8, 0.0],
            [0.0, 0.6, -0.8],
        ] {
            let q = rotation_from_x(d);
            assert!(close(rotate(&q, [1.0, 0.0, 0.0]), d), "{d:?}");
        }
    }

    #[test]
    fn the_surface_frames_rotation_maps_its_axes() {
        for n in [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.6, 0.0, 0.8],
        ] {
            let f = mmt::contact::SurfaceFrame::from_normal(n).unwrap();
            let rec = FrameRec {
                normal: f.normal,
                tangent1: f.tangent1,
                tangent2: f.tangent2,
            };
            let q = quaternion_of(&rec);
            assert!(close(rotate(&q, [0.0, 0.0, 1.0]), f.normal), "{n:?}");
            assert!(close(rotate(&q, [1.0, 0.0, 0.0]), f.tangent1), "{n:?}");
        }
    }
}
