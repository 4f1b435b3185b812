//! Loads a quadruped URDF (through urdf-rs) into a plain kinematic tree, checked against
//! the preset: a floating base, 12 revolute actuated joints and 4 feet. Fixed joints are
//! merged into their parent link, so the simulated tree has 13 bodies.

use std::collections::HashMap;
use std::path::Path;

use rapier3d::math::{Pose, Rotation, Vector};

use crate::error::{Error, Result};
use crate::preset::Preset;

/// A collision primitive in its link's frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Box with half extents.
    Cuboid(Vector),
    /// Cylinder along z: half height, radius.
    Cylinder(f32, f32),
    /// Capsule along z: half height of the segment, radius.
    Capsule(f32, f32),
    /// Sphere radius.
    Ball(f32),
}

/// A link of the merged tree.
#[derive(Debug, Clone)]
pub struct LinkModel {
    /// URDF name of the link (the parent, for merged links).
    pub name: String,
    /// Total mass (kg).
    pub mass: f32,
    /// Centre of mass in the link frame.
    pub com: Vector,
    /// Inertia tensor about the centre of mass, in the link frame (row-major 3x3).
    pub inertia: [[f32; 3]; 3],
    /// Collision primitives with their pose in the link frame (the feet's spheres are not
    /// among them: [`RobotModel::feet`] holds those).
    pub shapes: Vec<(Pose, Shape)>,
}

/// An actuated revolute joint of the merged tree.
#[derive(Debug, Clone)]
pub struct JointModel {
    /// URDF name.
    pub name: String,
    /// Index of the parent link in [`RobotModel::links`].
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// Joint frame in the parent link frame (URDF `origin`, fixed offsets folded in).
    pub origin: Pose,
    /// Unit rotation axis in the joint (= child) frame.
    pub axis: Vector,
    /// Position limits `[lower, upper]` (rad) from the URDF's `<limit>`, enforced by the
    /// simulation; `None` when the URDF gives none (lower = upper = 0, or a continuous joint).
    pub limits: Option<[f32; 2]>,
}

/// A quadruped ready to be built into a rapier world.
#[derive(Debug, Clone)]
pub struct RobotModel {
    /// Links; index 0 is the base.
    pub links: Vec<LinkModel>,
    /// The 12 actuated joints in preset (action) order.
    pub joints: Vec<JointModel>,
    /// For each foot: (link index, sphere centre in that link's frame, radius).
    pub feet: Vec<(usize, Vector, f32)>,
    /// Total mass (kg).
    pub total_mass: f32,
}

fn v3(v: &urdf_rs::Vec3) -> Vector {
    Vector::new(v.0[0] as f32, v.0[1] as f32, v.0[2] as f32)
}

fn pose(p: &urdf_rs::Pose) -> Pose {
    // URDF rpy: fixed-axis roll about x, then pitch about y, then yaw about z.
    let r = p.rpy.0;
    let rot = Rotation::from_euler(
        rapier3d::math::glamx::EulerRot::ZYX,
        r[2] as f32,
        r[1] as f32,
        r[0] as f32,
    );
    Pose::from_parts(v3(&p.xyz), rot)
}

fn rot_mat(r: Rotation) -> [[f32; 3]; 3] {
    let m = rapier3d::math::Matrix::from_quat(r);
    // glam matrices are column-major; return rows.
    let c = m.to_cols_array_2d();
    [
        [c[0][0], c[1][0], c[2][0]],
        [c[0][1], c[1][1], c[2][1]],
        [c[0][2], c[1][2], c[2][2]],
    ]
}

fn mat_mul(a: &[[f32; 3]; 3], b: &[[f32; 3]; 3]) -> [[f32; 3]; 3] {
    let mut o = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            o[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    o
}

fn transpose(a: &[[f32; 3]; 3]) -> [[f32; 3]; 3] {
    let mut o = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            o[i][j] = a[j][i];
        }
    }
    o
}

/// Inertia of `(mass, com, inertia about com)` bodies combined, about the combined com.
fn combine(parts: &[(f32, Vector, [[f32; 3]; 3])]) -> (f32, Vector, [[f32; 3]; 3]) {
    let m: f32 = parts.iter().map(|p| p.0).sum();
    if m <= 0.0 {
        return (0.0, Vector::ZERO, [[0.0; 3]; 3]);
    }
    let com = parts.iter().fold(Vector::ZERO, |a, p| a + p.1 * p.0) / m;
    let mut i = [[0.0f32; 3]; 3];
    for (pm, pc, pi) in parts {
        let d = *pc - com;
        let dd = d.dot(d);
        let da = [d.x, d.y, d.z];
        for r in 0..3 {
            for c in 0..3 {
                let delta = if r == c { 1.0 } else { 0.0 };
                i[r][c] += pi[r][c] + pm * (dd * delta - da[r] * da[c]);
            }
        }
    }
    (m, com, i)
}

fn shape(path: &Path, link: &str, g: &urdf_rs::Geometry) -> Result<Shape> {
    Ok(match g {
        urdf_rs::Geometry::Box { size } => Shape::Cuboid(v3(size) * 0.5),
        urdf_rs::Geometry::Cylinder { radius, length } => {
            Shape::Cylinder(*length as f32 * 0.5, *radius as f32)
        }
        urdf_rs::Geometry::Capsule { radius, length } => {
            Shape::Capsule(*length as f32 * 0.5, *radius as f32)
        }
        urdf_rs::Geometry::Sphere { radius } => Shape::Ball(*radius as f32),
        urdf_rs::Geometry::Mesh { filename, .. } => {
            return Err(Error::Urdf {
                path: path.to_path_buf(),
                element: format!("link {link}"),
                message: format!(
                    "mesh collision {filename:?} is not supported; use box, cylinder, capsule or sphere primitives"
                ),
            })
        }
    })
}

impl RobotModel {
    /// Parses and checks the preset's URDF, as read when the preset was loaded.
    pub fn load(preset: &Preset) -> Result<RobotModel> {
        Self::from_str(&preset.urdf_path, &preset.urdf_text, preset)
    }

    /// Parses URDF text (named `path` in errors) against the preset's joints and feet.
    pub fn from_str(path: &Path, text: &str, preset: &Preset) -> Result<RobotModel> {
        let err = |element: String, message: String| Error::Urdf {
            path: path.to_path_buf(),
            element,
            message,
        };
        let robot = urdf_rs::read_from_string(text)
            .map_err(|e| err("document".into(), format!("not a valid urdf: {e}")))?;
        let link_idx: HashMap<&str, usize> = robot
            .links
            .iter()
            .enumerate()
            .map(|(i, l)| (l.name.as_str(), i))
            .collect();
        for j in &robot.joints {
            for l in [&j.parent.link, &j.child.link] {
                if !link_idx.contains_key(l.as_str()) {
                    return Err(err(
                        format!("joint {}", j.name),
                        format!("refers to link {l:?}, which the file does not define"),
                    ));
                }
            }
        }
        // The base must be the root: a floating base is one no joint attaches to a parent,
        // or one attached to a parent by a `floating` joint.
        let base_name = preset.base_link.as_str();
        if !link_idx.contains_key(base_name) {
            return Err(err(
                format!("link {base_name}"),
                "base link named in the preset is missing".into(),
            ));
        }
        if let Some(j) = robot.joints.iter().find(|j| j.child.link == base_name) {
            if j.joint_type != urdf_rs::JointType::Floating {
                return Err(err(
                    format!("joint {}", j.name),
                    format!("attaches the base {base_name:?} to {:?} with a {:?} joint; expected a floating base (no parent joint)", j.parent.link, j.joint_type),
                ));
            }
        }
        // Actuated joints: exactly the preset's, all revolute.
        let movable = |t: &urdf_rs::JointType| {
            !matches!(t, urdf_rs::JointType::Fixed | urdf_rs::JointType::Floating)
        };
        for j in robot.joints.iter().filter(|j| movable(&j.joint_type)) {
            if !preset.joints.contains(&j.name) {
                return Err(err(
                    format!("joint {}", j.name),
                    format!("movable {:?} joint not listed in the preset's 12 actuated joints; make it fixed or list it", j.joint_type),
                ));
            }
        }
        for name in &preset.joints {
            match robot.joints.iter().find(|j| &j.name == name) {
                None => {
                    return Err(err(
                        format!("joint {name}"),
                        "actuated joint named in the preset is missing".into(),
                    ))
                }
                Some(j) if j.joint_type != urdf_rs::JointType::Revolute => {
                    return Err(err(
                        format!("joint {name}"),
                        format!("type {:?}; expected revolute", j.joint_type),
                    ))
                }
                Some(j) if v3(&j.axis.xyz).length() < 1e-6 => {
                    return Err(err(
                        format!("joint {name}"),
                        "axis is zero; expected a unit axis".into(),
                    ))
                }
                _ => {}
            }
        }
        for foot in &preset.feet {
            if !link_idx.contains_key(foot.as_str()) {
                return Err(err(
                    format!("link {foot}"),
                    "foot named in the preset is missing".into(),
                ));
            }
        }

        // Merge fixed joints: each URDF link maps to (merged body, pose in that body).
        let parent_joint: HashMap<&str, &urdf_rs::Joint> = robot
            .joints
            .iter()
            .map(|j| (j.child.link.as_str(), j))
            .collect();
        let mut body_of: HashMap<&str, (usize, Pose)> = HashMap::new();
        let mut bodies: Vec<&str> = vec![base_name];
        body_of.insert(base_name, (0, Pose::IDENTITY));
        for name in &preset.joints {
            let j = parent_joint
                .values()
                .find(|j| &j.name == name)
                .expect("checked above");
            bodies.push(j.child.link.as_str());
        }
        for (i, b) in bodies.iter().enumerate() {
            body_of.insert(b, (i, Pose::IDENTITY));
        }
        // Resolve every other link by walking up fixed joints to a body.
        for l in &robot.links {
            let mut chain = Pose::IDENTITY;
            let mut cur = l.name.as_str();
            let mut guard = 0;
            while !body_of.contains_key(cur) {
                let Some(j) = parent_joint.get(cur) else {
                    return Err(err(
                        format!("link {}", l.name),
                        "is not connected to the base".into(),
                    ));
                };
                if movable(&j.joint_type) || j.joint_type == urdf_rs::JointType::Floating {
                    return Err(err(
                        format!("link {}", l.name),
                        "hangs from a joint that is neither fixed nor actuated".into(),
                    ));
                }
                chain = pose(&j.origin) * chain;
                cur = j.parent.link.as_str();
                guard += 1;
                if guard > robot.links.len() {
                    return Err(err(format!("link {}", l.name), "kinematic loop".into()));
                }
            }
            let (b, p) = body_of[cur];
            body_of.insert(l.name.as_str(), (b, p * chain));
        }

        let mut links = Vec::with_capacity(bodies.len());
        for (bi, b) in bodies.iter().enumerate() {
            let mut parts = Vec::new();
            let mut shapes = Vec::new();
            for l in robot
                .links
                .iter()
                .filter(|l| body_of[l.name.as_str()].0 == bi)
            {
                let (_, lp) = body_of[l.name.as_str()];
                let ip = lp * pose(&l.inertial.origin);
                let it = &l.inertial.inertia;
                let local = [
                    [it.ixx as f32, it.ixy as f32, it.ixz as f32],
                    [it.ixy as f32, it.iyy as f32, it.iyz as f32],
                    [it.ixz as f32, it.iyz as f32, it.izz as f32],
                ];
                let r = rot_mat(ip.rotation);
                let world = mat_mul(&mat_mul(&r, &local), &transpose(&r));
                if l.inertial.mass.value < 0.0 {
                    return Err(err(format!("link {}", l.name), "negative mass".into()));
                }
                parts.push((l.inertial.mass.value as f32, ip.translation, world));
                if preset.feet.contains(&l.name) {
                    continue;
                }
                for c in &l.collision {
                    shapes.push((lp * pose(&c.origin), shape(path, &l.name, &c.geometry)?));
                }
            }
            let (mass, com, inertia) = combine(&parts);
            if mass <= 0.0 {
                return Err(err(
                    format!("link {b}"),
                    "has no mass; every moving body needs an <inertial>".into(),
                ));
            }
            links.push(LinkModel {
                name: b.to_string(),
                mass,
                com,
                inertia,
                shapes,
            });
        }

        let mut joints = Vec::with_capacity(12);
        for (k, name) in preset.joints.iter().enumerate() {
            let j = parent_joint
                .values()
                .find(|j| &j.name == name)
                .expect("checked above");
            let (pb, pp) = body_of[j.parent.link.as_str()];
            let (lo, hi) = (j.limit.lower as f32, j.limit.upper as f32);
            let limits = if lo == 0.0 && hi == 0.0 {
                None
            } else if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(err(
                    format!("joint {name}"),
                    format!("limit lower {lo} must be below upper {hi}"),
                ));
            } else {
                let q0 = preset.default_pose[k];
                if !(lo..=hi).contains(&q0) {
                    return Err(err(
                        format!("joint {name}"),
                        format!(
                            "the preset's default pose {q0} rad lies outside the limits [{lo}, {hi}]; \
                             widen the limits or change default_pose"
                        ),
                    ));
                }
                Some([lo, hi])
            };
            joints.push(JointModel {
                name: name.clone(),
                parent: pb,
                child: k + 1,
                origin: pp * pose(&j.origin),
                axis: v3(&j.axis.xyz).normalize(),
                limits,
            });
        }
        let mut feet = Vec::with_capacity(4);
        for foot in &preset.feet {
            let (b, fp) = body_of[foot.as_str()];
            let link = robot
                .links
                .iter()
                .find(|l| &l.name == foot)
                .expect("checked above");
            let radius = link.collision.iter().find_map(|c| match c.geometry {
                urdf_rs::Geometry::Sphere { radius } => Some(radius as f32),
                _ => None,
            });
            let Some(radius) = radius else {
                return Err(err(
                    format!("link {foot}"),
                    "foot has no sphere collision; expected one <sphere>".into(),
                ));
            };
            let centre = fp * pose(&link.collision[0].origin);
            feet.push((b, centre.translation, radius));
        }
        let total_mass = links.iter().map(|l| l.mass).sum();
        Ok(RobotModel {
            links,
            joints,
            feet,
            total_mass,
        })
    }
}
