//! One robot in its own rapier world: a floating-base multibody with explicit PD torques.

use std::sync::Arc;

use rapier3d::math::{Pose, Rotation, Vector};
use rapier3d::prelude::*;

use crate::preset::Preset;
use crate::terrain::Tile;
use crate::urdf::{RobotModel, Shape};

/// Collision group of the terrain.
const TERRAIN: Group = Group::GROUP_1;
/// Collision group of the robot's contact shapes (base and feet).
const ROBOT: Group = Group::GROUP_2;

/// Kinematic state of a robot read after a physics step.
#[derive(Debug, Clone, Copy, Default)]
pub struct BaseState {
    /// Base position (world).
    pub pos: Vector,
    /// Base orientation (world).
    pub rot: Rotation,
    /// Base linear velocity (world).
    pub linvel: Vector,
    /// Base angular velocity (world).
    pub angvel: Vector,
}

/// A robot and its terrain in one rapier world.
pub struct RobotWorld {
    world: PhysicsWorld,
    /// Rigid bodies: index 0 is the base, then one per actuated joint's child.
    bodies: Vec<RigidBodyHandle>,
    /// For each joint: (parent body index, child body index, axis in the child frame).
    joints: Vec<(usize, usize, Vector)>,
    /// Multibody link id of each joint's child body (multibody backend), empty otherwise.
    link_ids: Vec<usize>,
    /// Joint frames in the parent and child bodies (impulse backend reads angles from them).
    frames: Vec<(Pose, Pose)>,
    backend: JointBackend,
    base_collider: ColliderHandle,
    feet: Vec<ColliderHandle>,
    terrain: Option<ColliderHandle>,
    tile: Arc<Tile>,
    kp: f32,
    kd: f32,
    tau_max: f32,
    default_pose: Vec<f32>,
}

/// How the joints are simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointBackend {
    /// One reduced-coordinate multibody (exact joints, mass matrix rebuilt every substep).
    Multibody,
    /// Rigid bodies held together by impulse joint constraints.
    Impulse,
}

fn frame_for_axis(axis: Vector) -> Rotation {
    // rapier's revolute joint turns about the frame's local x: rotate x onto the axis.
    Rotation::from_rotation_arc(Vector::X, axis)
}

impl RobotWorld {
    /// Builds the robot at its spawn pose on `tile`.
    pub fn new(preset: &Preset, model: &RobotModel, tile: Arc<Tile>) -> RobotWorld {
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        let ip = &mut world.integration_parameters;
        ip.dt = preset.control.sim_dt;
        ip.num_solver_iterations = preset.control.solver_iterations;
        ip.num_internal_pgs_iterations = preset.control.pgs_iterations;
        let friction = preset.control.friction;

        let mut bodies = Vec::with_capacity(model.links.len());
        for link in &model.links {
            let i = link.inertia;
            let m = rapier3d::math::Matrix::from_cols_array_2d(&[
                [i[0][0], i[1][0], i[2][0]],
                [i[0][1], i[1][1], i[2][1]],
                [i[0][2], i[1][2], i[2][2]],
            ]);
            let mp = MassProperties::with_inertia_matrix(link.com, link.mass, m);
            let rb = RigidBodyBuilder::dynamic()
                .additional_mass_properties(mp)
                .can_sleep(false)
                .build();
            bodies.push(world.bodies.insert(rb));
        }
        // Only the base and the feet touch the terrain; legs have no colliders (no
        // self-contacts, no knee contacts), which keeps the narrow phase small.
        let groups = InteractionGroups::new(ROBOT, TERRAIN, InteractionTestMode::And);
        let mut base_collider = None;
        for (pose, shape) in &model.links[0].shapes {
            let sh = match *shape {
                Shape::Cuboid(h) => SharedShape::cuboid(h.x, h.y, h.z),
                Shape::Cylinder(hh, r) => SharedShape::cylinder(hh, r),
                Shape::Capsule(hh, r) => SharedShape::capsule_z(hh, r),
                Shape::Ball(r) => SharedShape::ball(r),
            };
            let c = ColliderBuilder::new(sh)
                .position(*pose)
                .density(0.0)
                .friction(friction)
                .collision_groups(groups)
                .build();
            let h = world
                .colliders
                .insert_with_parent(c, bodies[0], &mut world.bodies);
            base_collider.get_or_insert(h);
        }
        let base_collider =
            base_collider.expect("base has a collision shape (checked by the preset)");
        let feet = model
            .feet
            .iter()
            .map(|&(body, centre, r)| {
                let c = ColliderBuilder::ball(r)
                    .translation(centre)
                    .density(0.0)
                    .friction(friction)
                    .collision_groups(groups)
                    .build();
                world
                    .colliders
                    .insert_with_parent(c, bodies[body], &mut world.bodies)
            })
            .collect();

        let backend = preset.control.joints;
        let mut joints = Vec::with_capacity(model.joints.len());
        let mut handles = Vec::with_capacity(model.joints.len());
        let mut frames = Vec::with_capacity(model.joints.len());
        for j in &model.joints {
            let f = frame_for_axis(j.axis);
            let (f1, f2) = (j.origin * Pose::from_rotation(f), Pose::from_rotation(f));
            let joint = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
                .local_frame1(f1)
                .local_frame2(f2)
                .contacts_enabled(false)
                .build();
            match backend {
                JointBackend::Multibody => handles.push(
                    world
                        .multibody_joints
                        .insert(bodies[j.parent], bodies[j.child], joint, true)
                        .expect("a tree of revolute joints forms one multibody"),
                ),
                JointBackend::Impulse => {
                    world
                        .impulse_joints
                        .insert(bodies[j.parent], bodies[j.child], joint, true);
                }
            }
            frames.push((f1, f2));
            joints.push((j.parent, j.child, j.axis));
        }
        let link_ids = handles
            .iter()
            .map(|h| world.multibody_joints.get(*h).expect("just inserted").1)
            .collect();
        if let Some(h) = handles.first() {
            let (mb, _) = world.multibody_joints.get_mut(*h).expect("just inserted");
            mb.set_self_contacts_enabled(false);
        }

        let mut rw = RobotWorld {
            world,
            bodies,
            joints,
            link_ids,
            frames,
            backend,
            base_collider,
            feet,
            terrain: None,
            tile: tile.clone(),
            kp: preset.control.stiffness,
            kd: preset.control.damping,
            tau_max: preset.control.torque_limit,
            default_pose: preset.default_pose.clone(),
        };
        rw.set_tile(tile);
        rw
    }

    /// Replaces the terrain collider (curriculum level changes).
    pub fn set_tile(&mut self, tile: Arc<Tile>) {
        if let Some(h) = self.terrain.take() {
            let w = &mut self.world;
            w.colliders
                .remove(h, &mut w.islands, &mut w.bodies, &mut w.soft_bodies, false);
        }
        let groups = InteractionGroups::new(TERRAIN, ROBOT, InteractionTestMode::And);
        let builder = match &tile.grid {
            None => ColliderBuilder::cuboid(crate::terrain::TILE, crate::terrain::TILE, 1.0)
                .translation(Vector::new(0.0, 0.0, -1.0)),
            Some(g) => {
                // parry's heightfield lies in its local xz plane with y up; turn it so that
                // local y is world z. Row i then runs along world -y.
                let n = g.n;
                let heights =
                    rapier3d::parry::utils::Array2::from_fn(n, n, |i, j| g.h[j * n + (n - 1 - i)]);
                let side = g.side();
                ColliderBuilder::heightfield(heights, Vector::new(side, 1.0, side))
                    .rotation(Vector::new(std::f32::consts::FRAC_PI_2, 0.0, 0.0))
            }
        };
        let c = builder
            .friction(self.world.colliders[self.base_collider].friction())
            .collision_groups(groups)
            .build();
        self.terrain = Some(self.world.colliders.insert(c));
        self.tile = tile;
    }

    /// The tile the robot stands on.
    pub fn tile(&self) -> &Arc<Tile> {
        &self.tile
    }

    /// Puts the robot at `(x, y)` above the terrain with yaw `yaw`, joints at `q`, at rest.
    pub fn reset(&mut self, x: f32, y: f32, z: f32, yaw: f32, q: &[f32]) {
        self.reset_with_rotation(x, y, z, Rotation::from_rotation_z(yaw), q);
    }

    /// Puts the base at `(x, y, z)` with orientation `rot`, joints at `q`, at rest.
    pub fn reset_with_rotation(&mut self, x: f32, y: f32, z: f32, rot: Rotation, q: &[f32]) {
        let target = Pose::from_parts(Vector::new(x, y, z), rot);
        if self.backend == JointBackend::Impulse {
            // Forward kinematics by hand: joints are listed parents first.
            let mut poses = vec![Pose::IDENTITY; self.bodies.len()];
            poses[0] = target;
            for (k, &(parent, child, _)) in self.joints.iter().enumerate() {
                let (f1, f2) = self.frames[k];
                poses[child] = poses[parent]
                    * f1
                    * Pose::from_rotation(Rotation::from_rotation_x(q[k]))
                    * f2.inverse();
            }
            for (h, p) in self.bodies.iter().zip(&poses) {
                self.world.bodies[*h].set_position(*p, false);
            }
            self.zero_velocities();
            return;
        }
        let link_ids = std::mem::take(&mut self.link_ids);
        let (mb, _) = self.multibody_mut_with_bodies();
        let ndofs = mb.ndofs();
        let mut disp = vec![0.0f32; ndofs];
        let root = mb.root().joint();
        let c = root.coords();
        let cur_rot = root.joint_rot();
        disp[0] = target.translation.x - c[0];
        disp[1] = target.translation.y - c[1];
        disp[2] = target.translation.z - c[2];
        let d = (target.rotation * cur_rot.inverse())
            .normalize()
            .to_scaled_axis();
        disp[3] = d.x;
        disp[4] = d.y;
        disp[5] = d.z;
        for (k, &id) in link_ids.iter().enumerate() {
            let link = mb.link(id).expect("link exists");
            disp[link.assembly_id()] = q[k] - link.joint().coords()[3];
        }
        self.link_ids = link_ids;
        let (mb, _) = self.multibody_mut_with_bodies();
        mb.apply_displacements(&disp);
        mb.generalized_velocity_mut().fill(0.0);
        self.sync_bodies();
    }

    fn multibody_index(&self) -> MultibodyIndex {
        self.world
            .multibody_joints
            .rigid_body_link(self.bodies[1])
            .expect("robot is a multibody")
            .multibody
    }

    /// The robot's multibody and the rigid-body set, borrowed together.
    fn multibody_mut_with_bodies(&mut self) -> (&mut Multibody, &mut RigidBodySet) {
        let h = self.multibody_index();
        let w = &mut self.world;
        let mb = w
            .multibody_joints
            .get_multibody_mut(h)
            .expect("multibody exists");
        (mb, &mut w.bodies)
    }

    fn sync_bodies(&mut self) {
        let (mb, bodies) = self.multibody_mut_with_bodies();
        mb.forward_kinematics(bodies, false);
        mb.update_rigid_bodies(bodies, true);
        self.zero_velocities();
    }

    fn zero_velocities(&mut self) {
        for h in &self.bodies {
            let rb = &mut self.world.bodies[*h];
            rb.set_linvel(Vector::ZERO, false);
            rb.set_angvel(Vector::ZERO, false);
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
    }

    fn multibody(&self) -> &Multibody {
        let h = self.multibody_index();
        self.world
            .multibody_joints
            .get_multibody(h)
            .expect("multibody exists")
    }

    /// Joint positions and velocities in action order.
    pub fn joint_state(&self, q: &mut [f32], qd: &mut [f32]) {
        if self.backend == JointBackend::Impulse {
            for (k, &(parent, child, _)) in self.joints.iter().enumerate() {
                let (f1, f2) = &self.frames[k];
                let (p, c) = (
                    &self.world.bodies[self.bodies[parent]],
                    &self.world.bodies[self.bodies[child]],
                );
                let r1 = *p.rotation() * f1.rotation;
                let r2 = *c.rotation() * f2.rotation;
                let rel = r1.inverse() * r2;
                // Rotation about the frame's x: angle from the quaternion's x and w parts.
                let rel = if rel.w < 0.0 { -rel } else { rel };
                q[k] = 2.0 * rel.x.atan2(rel.w);
                qd[k] = (c.angvel() - p.angvel()).dot(r1 * Vector::X);
            }
            return;
        }
        let mb = self.multibody();
        let v = mb.generalized_velocity();
        for (k, &id) in self.link_ids.iter().enumerate() {
            let link = mb.link(id).expect("link exists");
            q[k] = link.joint().coords()[3];
            qd[k] = v[link.assembly_id()];
        }
    }

    /// One physics step with the PD law toward `targets`; writes the applied torques.
    pub fn step(&mut self, targets: &[f32], q: &mut [f32], qd: &mut [f32], tau: &mut [f32]) {
        self.joint_state(q, qd);
        for k in 0..tau.len() {
            tau[k] = (self.kp * (targets[k] - q[k]) - self.kd * qd[k])
                .clamp(-self.tau_max, self.tau_max);
        }
        for h in &self.bodies {
            self.world.bodies[*h].reset_torques(false);
        }
        for (k, &(parent, child, axis)) in self.joints.iter().enumerate() {
            let axis_w = *self.world.bodies[self.bodies[child]].rotation() * axis;
            let t = axis_w * tau[k];
            self.world.bodies[self.bodies[child]].add_torque(t, false);
            self.world.bodies[self.bodies[parent]].add_torque(-t, false);
        }
        self.world.step();
    }

    /// Base pose and velocities.
    pub fn base(&self) -> BaseState {
        let rb = &self.world.bodies[self.bodies[0]];
        BaseState {
            pos: rb.translation(),
            rot: *rb.rotation(),
            linvel: rb.linvel(),
            angvel: rb.angvel(),
        }
    }

    fn touching(&self, c: ColliderHandle) -> bool {
        let Some(t) = self.terrain else { return false };
        self.world
            .narrow_phase
            .contact_pair(c, t)
            .is_some_and(|p| p.has_any_active_contact())
    }

    /// Whether each foot touches the terrain.
    pub fn foot_contacts(&self, out: &mut [bool]) {
        for (o, f) in out.iter_mut().zip(&self.feet) {
            *o = self.touching(*f);
        }
    }

    /// Whether the base touches the terrain (a fall).
    pub fn base_contact(&self) -> bool {
        self.touching(self.base_collider)
    }

    /// World positions of every body (for rendering), base first.
    pub fn body_positions(&self) -> Vec<Vector> {
        self.bodies
            .iter()
            .map(|h| self.world.bodies[*h].translation())
            .collect()
    }

    /// World positions of the feet (sphere centres).
    pub fn foot_positions(&self) -> Vec<Vector> {
        self.feet
            .iter()
            .map(|h| self.world.colliders[*h].position().translation)
            .collect()
    }

    /// The default joint pose.
    pub fn default_pose(&self) -> &[f32] {
        &self.default_pose
    }

    /// Casts a vertical ray through the terrain collider at (x, y): the physics' own view
    /// of the ground height (tests compare it with the tile's heights).
    pub fn ray_height(&mut self, x: f32, y: f32) -> Option<f32> {
        let t = self.terrain?;
        let c = &self.world.colliders[t];
        // parry's heightfield ray cast walks cells in the ray's horizontal projection, which
        // a perfectly vertical ray does not have: start 20 m up with a 1e-4 slant aimed at (x, y, 0).
        let d = Vector::new(1e-4, 1e-4, -1.0).normalize();
        let ray = Ray::new(
            Vector::new(x - d.x * (20.0 / -d.z), y - d.y * (20.0 / -d.z), 20.0),
            d,
        );
        c.shape()
            .cast_ray(c.position(), &ray, 100.0, true)
            .map(|toi| ray.point_at(toi).z)
    }
}
