//! One robot in its own rapier world: a floating-base multibody with explicit PD torques.

use std::sync::Arc;

use rapier3d::math::{Pose, Rotation, Vector};
use rapier3d::parry::query::{DefaultQueryDispatcher, QueryDispatcher};
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
    /// Thigh and shank shapes (every collision shape of a leg body but the feet): they
    /// touch the terrain, and legged_gym's `collision` term counts their contacts.
    legs: Vec<ColliderHandle>,
    /// Joint position limits in action order (`None`: unlimited).
    limits: Vec<Option<[f32; 2]>>,
    terrain: Option<ColliderHandle>,
    tile: Arc<Tile>,
    kp: f32,
    kd: f32,
    tau_max: f32,
    /// For each joint, the bodies that move with its child (the child and its descendants).
    subtrees: Vec<Vec<usize>>,
    /// Mass, centre of mass (body frame) and inertia about it (body frame) of every body.
    inertia: Vec<(f32, Vector, rapier3d::math::Matrix)>,
    default_pose: Vec<f32>,
}

pub use gaitsweep_model::preset::{CapsuleContacts, JointBackend};

/// The rapier shape of a URDF primitive. Cylinders become capsules of the same radius and
/// length when `capsules` is set (legged_gym's `replace_cylinder_with_capsule`): rapier's
/// capsule-terrain contacts are analytic, its cylinder ones iterative.
pub(crate) fn shared_shape(shape: &Shape, capsules: bool) -> SharedShape {
    match *shape {
        Shape::Cuboid(h) => SharedShape::cuboid(h.x, h.y, h.z),
        Shape::Cylinder(hh, r) if capsules => SharedShape::capsule_z(hh, r),
        Shape::Cylinder(hh, r) => SharedShape::cylinder(hh, r),
        Shape::Capsule(hh, r) => SharedShape::capsule_z(hh, r),
        Shape::Ball(r) => SharedShape::ball(r),
    }
}

fn frame_for_axis(axis: Vector) -> Rotation {
    // rapier's revolute joint turns about the frame's local x: rotate x onto the axis.
    Rotation::from_rotation_arc(Vector::X, axis)
}

impl RobotWorld {
    /// Builds the robot at its spawn pose on `tile`.
    pub fn new(preset: &Preset, model: &RobotModel, tile: Arc<Tile>) -> RobotWorld {
        let mut world = PhysicsWorld::new();
        if preset.control.capsule_contacts == CapsuleContacts::ClosedForm {
            world.narrow_phase = NarrowPhase::with_query_dispatcher(
                crate::contact::CapsuleTerrainDispatcher.chain(DefaultQueryDispatcher),
            );
        }
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
        // Every robot shape touches the terrain, none touches another part of the robot
        // (legged_gym turns ANYmal's self-collisions off).
        let groups = InteractionGroups::new(ROBOT, TERRAIN, InteractionTestMode::And);
        let capsules = preset.control.capsule_legs;
        let mut base_collider = None;
        let mut legs = Vec::new();
        for (bi, link) in model.links.iter().enumerate() {
            if bi > 0 && !preset.control.leg_collisions {
                continue;
            }
            for (pose, shape) in &link.shapes {
                let c = ColliderBuilder::new(shared_shape(shape, capsules))
                    .position(*pose)
                    .density(0.0)
                    .friction(friction)
                    .collision_groups(groups)
                    .build();
                let h = world
                    .colliders
                    .insert_with_parent(c, bodies[bi], &mut world.bodies);
                if bi == 0 {
                    base_collider.get_or_insert(h);
                } else {
                    legs.push(h);
                }
            }
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
        let mut pending = Vec::new();
        for j in &model.joints {
            let f = frame_for_axis(j.axis);
            let (f1, f2) = (j.origin * Pose::from_rotation(f), Pose::from_rotation(f));
            let mut builder = GenericJointBuilder::new(JointAxesMask::LOCKED_REVOLUTE_AXES)
                .local_frame1(f1)
                .local_frame2(f2)
                .contacts_enabled(false);
            if let (Some(lim), JointBackend::Multibody) = (j.limits, backend) {
                // The joint angle is the rotation of frame 2 about frame 1's x (the axis).
                // Impulse joints get the projection of `enforce_limits` instead: rapier
                // 0.36's limit rows on chains of impulse joints at the preset's one solver
                // iteration held some legs and let others pass 2 rad beyond their limits,
                // depending on insertion order; stop torques were unstable on the heavy
                // robot (measured with sim/tests/legs.rs, see BENCHMARKS.md).
                builder = builder.limits(JointAxis::AngX, lim);
            }
            let joint = builder.build();
            match backend {
                JointBackend::Multibody => handles.push(
                    world
                        .multibody_joints
                        .insert(bodies[j.parent], bodies[j.child], joint, true)
                        .expect("a tree of revolute joints forms one multibody"),
                ),
                JointBackend::Impulse => {
                    pending.push((bodies[j.parent], bodies[j.child], joint));
                }
            }
            frames.push((f1, f2));
            joints.push((j.parent, j.child, j.axis));
        }
        for (a, b, joint) in pending {
            world.impulse_joints.insert(a, b, joint, true);
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
            legs,
            limits: model.joints.iter().map(|j| j.limits).collect(),
            terrain: None,
            tile: tile.clone(),
            kp: preset.control.stiffness,
            kd: preset.control.damping,
            tau_max: preset.control.torque_limit,
            subtrees: (0..model.joints.len())
                .map(|k| {
                    let mut sub = vec![model.joints[k].child];
                    // Joints are listed parents first: a later joint whose parent is in the
                    // subtree brings its child in.
                    for j in &model.joints[k + 1..] {
                        if sub.contains(&j.parent) {
                            sub.push(j.child);
                        }
                    }
                    sub
                })
                .collect(),
            inertia: model
                .links
                .iter()
                .map(|l| {
                    let i = l.inertia;
                    let m = rapier3d::math::Matrix::from_cols_array_2d(&[
                        [i[0][0], i[1][0], i[2][0]],
                        [i[0][1], i[1][1], i[2][1]],
                        [i[0][2], i[1][2], i[2][2]],
                    ]);
                    (l.mass, l.com, m)
                })
                .collect(),
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
        // Every world on a tile shares its heightfield (one Arc), built once per tile.
        let builder = match &tile.collider {
            None => ColliderBuilder::cuboid(crate::terrain::TILE, crate::terrain::TILE, 1.0)
                .translation(Vector::new(0.0, 0.0, -1.0)),
            Some(shape) => ColliderBuilder::new(shape.clone()).rotation(Vector::new(
                std::f32::consts::FRAC_PI_2,
                0.0,
                0.0,
            )),
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
            for k in 0..self.joints.len() {
                let (angle, axis, w_rel) = self.impulse_joint(k);
                q[k] = angle;
                qd[k] = w_rel.dot(axis);
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

    /// One physics step with the PD law toward `targets`; writes the applied (actuator)
    /// torques. Joint limits then hold as hard stops (see [`Self::enforce_limits`]).
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
        if self.backend == JointBackend::Impulse {
            self.enforce_limits();
        }
    }

    /// Angle of impulse joint `k`, its axis in the world, and the child's angular velocity
    /// relative to the parent.
    fn impulse_joint(&self, k: usize) -> (f32, Vector, Vector) {
        let (parent, child, _) = self.joints[k];
        let (f1, f2) = &self.frames[k];
        let (p, c) = (
            &self.world.bodies[self.bodies[parent]],
            &self.world.bodies[self.bodies[child]],
        );
        let r1 = *p.rotation() * f1.rotation;
        let rel = r1.inverse() * (*c.rotation() * f2.rotation);
        // Rotation about the frame's x: angle from the quaternion's x and w parts.
        let rel = if rel.w < 0.0 { -rel } else { rel };
        (
            2.0 * rel.x.atan2(rel.w),
            r1 * Vector::X,
            c.angvel() - p.angvel(),
        )
    }

    /// Moment of inertia of `bodies` about the line through `pivot` along unit `axis`.
    fn inertia_about(
        &self,
        bodies: impl Iterator<Item = usize>,
        pivot: Vector,
        axis: Vector,
    ) -> f32 {
        bodies
            .map(|b| {
                let rb = &self.world.bodies[self.bodies[b]];
                let (m, com, ic) = &self.inertia[b];
                let rot = *rb.rotation();
                let a = rot.inverse() * axis;
                let r = rb.position() * *com - pivot;
                a.dot(*ic * a) + m * r.cross(axis).length_squared()
            })
            .sum()
    }

    /// Turns `bodies` rigidly by `angle` about the line through `pivot` along `axis`, and
    /// adds the angular velocity `dw` about that line.
    fn turn(&mut self, bodies: &[usize], pivot: Vector, axis: Vector, angle: f32, dw: f32) {
        let r = Rotation::from_axis_angle(axis, angle);
        for &b in bodies {
            let com = self.inertia[b].1;
            let rb = &mut self.world.bodies[self.bodies[b]];
            let p = *rb.position();
            let moved = Pose::from_parts(pivot + r * (p.translation - pivot), r * p.rotation);
            rb.set_position(moved, false);
            let w = dw * axis;
            let v = rb.linvel() + w.cross(moved * com - pivot);
            rb.set_linvel(v, false);
            rb.set_angvel(rb.angvel() + w, false);
        }
    }

    /// Hard joint stops for the impulse backend: after a physics step, a joint past its
    /// URDF limit is put back on it, the two sides turned about the joint axis in inverse
    /// proportion to their inertia about it (so the robot's angular momentum about the axis
    /// is kept), and the relative velocity carrying it further out is removed the same way
    /// (a perfectly inelastic stop). Joints are visited parents first; turning one side of
    /// a joint rigidly leaves every other joint angle unchanged.
    fn enforce_limits(&mut self) {
        for k in 0..self.joints.len() {
            let Some([lo, hi]) = self.limits[k] else {
                continue;
            };
            let (q, axis, w_rel) = self.impulse_joint(k);
            if (lo..=hi).contains(&q) {
                continue;
            }
            let w_rel = w_rel.dot(axis);
            let (parent, f1) = (self.joints[k].0, self.frames[k].0);
            let pivot = *self.world.bodies[self.bodies[parent]].position() * f1.translation;
            let sub = std::mem::take(&mut self.subtrees[k]);
            let rest: Vec<usize> = (0..self.bodies.len())
                .filter(|b| !sub.contains(b))
                .collect();
            let ic = self
                .inertia_about(sub.iter().copied(), pivot, axis)
                .max(1e-9);
            let ip = self
                .inertia_about(rest.iter().copied(), pivot, axis)
                .max(1e-9);
            let (sc, sp) = (ip / (ic + ip), ic / (ic + ip));
            let dq = q.clamp(lo, hi) - q;
            // Remove only the part of the relative velocity that goes further out.
            let out = if q > hi {
                w_rel.max(0.0)
            } else {
                w_rel.min(0.0)
            };
            self.turn(&sub, pivot, axis, dq * sc, -out * sc);
            self.turn(&rest, pivot, axis, -dq * sp, out * sp);
            self.subtrees[k] = sub;
        }
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

    /// Number of leg shapes (thighs, shanks) touching the terrain: legged_gym's
    /// `collision` term.
    pub fn leg_contacts(&self) -> usize {
        self.legs.iter().filter(|c| self.touching(**c)).count()
    }

    /// Joint position limits in action order (`None`: unlimited).
    pub fn joint_limits(&self) -> &[Option<[f32; 2]>] {
        &self.limits
    }

    /// Moves the whole robot by `(dx, dy)`, keeping every velocity: on a terrain that
    /// repeats every `|dx|`, `|dy|` metres nothing the robot feels changes.
    pub fn shift(&mut self, dx: f32, dy: f32) {
        let d = Vector::new(dx, dy, 0.0);
        for h in &self.bodies {
            let rb = &mut self.world.bodies[*h];
            let mut p = *rb.position();
            p.translation += d;
            rb.set_position(p, false);
        }
    }

    /// Sets the friction coefficient of every robot shape (legged_gym's friction
    /// randomization; rapier averages it with the terrain's, as PhysX does by default).
    pub fn set_robot_friction(&mut self, friction: f32) {
        let shapes = std::iter::once(self.base_collider)
            .chain(self.legs.iter().copied())
            .chain(self.feet.iter().copied());
        for h in shapes {
            self.world.colliders[h].set_friction(friction);
        }
    }

    /// Sets the base's horizontal velocity to `(vx, vy)` (world), keeping the joint
    /// velocities: every body gets the same change, as legged_gym's push sets the root
    /// state of an articulation.
    pub fn push_base(&mut self, vx: f32, vy: f32) {
        let v0 = self.world.bodies[self.bodies[0]].linvel();
        let dv = Vector::new(vx - v0.x, vy - v0.y, 0.0);
        if self.backend == JointBackend::Multibody {
            let (mb, bodies) = self.multibody_mut_with_bodies();
            // A free root's first three generalized velocities are its linear velocity.
            let mut v = mb.generalized_velocity_mut();
            v[0] += dv.x;
            v[1] += dv.y;
            mb.update_rigid_bodies(bodies, true);
            return;
        }
        for h in &self.bodies {
            let rb = &mut self.world.bodies[*h];
            rb.set_linvel(rb.linvel() + dv, false);
        }
    }

    /// Sets the base's linear and angular velocity (world frame), the legs moving with it
    /// as one rigid body (legged_gym's `_reset_root_states`).
    pub fn set_base_velocity(&mut self, lin: Vector, ang: Vector) {
        if self.backend == JointBackend::Multibody {
            let (mb, bodies) = self.multibody_mut_with_bodies();
            // A free root's generalized velocities: linear, then angular, world frame.
            let mut v = mb.generalized_velocity_mut();
            for i in 0..3 {
                v[i] = lin[i];
                v[3 + i] = ang[i];
            }
            mb.update_rigid_bodies(bodies, true);
            // The link bodies' own velocities are what the next observation reads; rapier
            // copies the multibody's into them only in a step.
        }
        let origin = self.world.bodies[self.bodies[0]].translation();
        for h in &self.bodies {
            let rb = &mut self.world.bodies[*h];
            let r = rb.translation() - origin;
            rb.set_linvel(lin + ang.cross(r), false);
            rb.set_angvel(ang, false);
        }
    }

    /// Height of the lowest foot shape's centre (world), from the bodies' current poses,
    /// so it holds right after a reset, before any step.
    pub fn lowest_foot_z(&self) -> f32 {
        self.feet
            .iter()
            .map(|h| self.collider_center(*h).z)
            .fold(f32::INFINITY, f32::min)
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
        self.feet.iter().map(|h| self.collider_center(*h)).collect()
    }

    /// A collider's centre from its body's pose: rapier moves colliders with their bodies
    /// only in a step, so right after a reset `Collider::position` is stale.
    fn collider_center(&self, h: ColliderHandle) -> Vector {
        let c = &self.world.colliders[h];
        match (c.parent(), c.position_wrt_parent()) {
            (Some(b), Some(rel)) => (*self.world.bodies[b].position() * *rel).translation,
            _ => c.position().translation,
        }
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
