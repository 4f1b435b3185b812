//! Capsule-heightfield contacts in closed form: a query dispatcher that rapier's narrow
//! phase asks first (parry's own dispatcher answers every other pair).
//!
//! parry builds one manifold per heightfield triangle under a capsule, each from a GJK
//! query, its polygonal features and the triangle's pseudo-normals; the solver then merges
//! them back into clusters. Under a shank lying on rough ground that is 4-8 triangles per
//! capsule and substep, and it was most of what the leg colliders cost (BENCHMARKS.md,
//! "Leg colliders and joint limits"). A capsule is rigid: it rests on at most a few points
//! of the surface. This module asks three questions of the surface, each in closed form
//! (Ericson, *Real-Time Collision Detection*, 5.1.5 and 5.1.9): where the surface is
//! nearest to each end cap's centre, and where it is nearest to the axis in between. Each
//! answer within the prediction distance becomes a one-point manifold with its own normal
//! (rapier's contact clustering merges those that share a plane), so a capsule lying on
//! the ground stands on its two ends and one across a stair edge rests on the edge.
//!
//! An end cap whose centre lies under the surface (a deep penetration) is pushed out along
//! the normal of the triangle above it, by its depth below that triangle's plane.

use rapier3d::parry::math::{Pose, Real, Vector};
use rapier3d::parry::query::closest_points::closest_points_segment_segment_with_locations_nD;
use rapier3d::parry::query::details::NormalConstraints;
use rapier3d::parry::query::PointQuery;
use rapier3d::parry::query::{
    ClosestPoints, Contact, ContactManifold, ContactManifoldsWorkspace, NonlinearRigidMotion,
    PersistentQueryDispatcher, QueryDispatcher, ShapeCastHit, ShapeCastOptions, ShapeDistance,
    ShapeIntersection, TrackedContact, TypedWorkspaceData, Unsupported, WorkspaceData,
};
use rapier3d::parry::shape::{
    Capsule, HeightField, PackedFeatureId, SegmentPointLocation, Shape, Triangle,
};

/// Answers capsule-heightfield contact manifolds in closed form, nothing else (chain it
/// before parry's `DefaultQueryDispatcher`).
#[derive(Debug, Clone, Copy, Default)]
pub struct CapsuleTerrainDispatcher;

/// One contact between the capsule and the surface, in the heightfield's frame.
#[derive(Debug, Clone, Copy)]
struct Probe {
    /// Signed gap between the capsule's surface and the terrain (negative: penetration).
    dist: Real,
    /// Contact point on the capsule's surface.
    on_capsule: Vector,
    /// Contact point on the terrain.
    on_terrain: Vector,
    /// Unit normal from the terrain toward the capsule.
    normal: Vector,
}

/// The triangle's unit normal on the side of the heightfield's up axis (local y).
fn up_normal(t: &Triangle) -> Option<Vector> {
    let n = (t.b - t.a).cross(t.c - t.a);
    let n = n.try_normalize()?;
    Some(if n.y < 0.0 { -n } else { n })
}

/// Closest point of triangle `t` to `p` (parry's projection, Ericson 5.1.5).
fn closest_on_triangle(p: Vector, t: &Triangle) -> Vector {
    t.project_local_point(p, true).point
}

/// Closest points of segments `p1 q1` and `p2 q2` (parry's, Ericson 5.1.9): the parameter
/// along the first and both points.
fn closest_segment_segment(
    p1: Vector,
    q1: Vector,
    p2: Vector,
    q2: Vector,
) -> (Real, Vector, Vector) {
    let (l1, l2) = closest_points_segment_segment_with_locations_nD((&p1, &q1), (&p2, &q2));
    let param = |l: SegmentPointLocation| match l {
        SegmentPointLocation::OnVertex(0) => 0.0,
        SegmentPointLocation::OnVertex(_) => 1.0,
        SegmentPointLocation::OnEdge([_, s]) => s,
    };
    let (s, t) = (param(l1), param(l2));
    (s, p1 + (q1 - p1) * s, p2 + (q2 - p2) * t)
}

/// `p`'s signed distance to the plane of the heightfield triangle under its vertical, and
/// that triangle's normal, when `p` lies below the surface (inside the ground).
fn below_surface(hf: &HeightField, p: Vector) -> Option<(Real, Vector)> {
    let (i, j) = hf.cell_at_point(p)?;
    let (t1, t2) = hf.triangles_at(i, j);
    // The triangle whose horizontal shadow holds (x, z) best: a point on a cell's border,
    // or off it by rounding, still finds one.
    let mut best: Option<(Real, Triangle, Vector)> = None;
    for t in [t1, t2].into_iter().flatten() {
        let Some(n) = up_normal(&t) else { continue };
        let inside = horizontal_barycentric_min(p, &t);
        if best.is_none_or(|(b, _, _)| inside > b) {
            best = Some((inside, t, n));
        }
    }
    let (_, t, n) = best?;
    // Height of the triangle's plane above (x, z).
    let y = t.a.y - (n.x * (p.x - t.a.x) + n.z * (p.z - t.a.z)) / n.y;
    (p.y < y).then(|| ((p - t.a).dot(n), n))
}

/// The smallest barycentric coordinate of `p`'s horizontal (x, z) position in the
/// triangle's horizontal shadow: >= 0 inside.
fn horizontal_barycentric_min(p: Vector, t: &Triangle) -> Real {
    let (ax, az) = (t.a.x, t.a.z);
    let (e1x, e1z) = (t.b.x - ax, t.b.z - az);
    let (e2x, e2z) = (t.c.x - ax, t.c.z - az);
    let det = e1x * e2z - e2x * e1z;
    if det.abs() < 1.0e-12 {
        return Real::MIN;
    }
    let (px, pz) = (p.x - ax, p.z - az);
    let u = (px * e2z - e2x * pz) / det;
    let v = (e1x * pz - px * e1z) / det;
    u.min(v).min(1.0 - u - v)
}

/// The nearest surface point found so far for a point of the capsule's axis.
#[derive(Clone, Copy)]
struct Nearest {
    dist_sq: Real,
    on_axis: Vector,
    on_terrain: Vector,
    /// Face normal of the triangle it lies on (used when the gap is zero).
    face: Vector,
}

impl Nearest {
    const NONE: Nearest = Nearest {
        dist_sq: Real::MAX,
        on_axis: Vector::ZERO,
        on_terrain: Vector::ZERO,
        face: Vector::Y,
    };

    fn offer(&mut self, on_axis: Vector, on_terrain: Vector, face: Vector) {
        let d = on_axis.distance_squared(on_terrain);
        if d < self.dist_sq {
            *self = Nearest {
                dist_sq: d,
                on_axis,
                on_terrain,
                face,
            };
        }
    }

    fn probe(&self, radius: Real) -> Option<Probe> {
        if self.dist_sq == Real::MAX {
            return None;
        }
        let d = self.dist_sq.sqrt();
        let normal = if d > 1.0e-6 {
            (self.on_axis - self.on_terrain) / d
        } else {
            self.face
        };
        Some(Probe {
            dist: d - radius,
            on_capsule: self.on_axis - normal * radius,
            on_terrain: self.on_terrain,
            normal,
        })
    }
}

/// Whether something in the box `[lo2, hi2]` may lie over something in `[lo1, hi1]`:
/// their horizontal (x, z) shadows overlap and the second reaches above the first's bottom.
fn may_lie_over(lo1: Vector, hi1: Vector, lo2: Vector, hi2: Vector) -> bool {
    lo1.x <= hi2.x && lo2.x <= hi1.x && lo1.z <= hi2.z && lo2.z <= hi1.z && hi2.y > lo1.y
}

/// How far edge `e0 e1` lies above axis `a b` where their horizontal (x, z) shadows cross,
/// measured between the two segments, with their closest points (on the axis, on the
/// edge); `None` where the shadows do not cross or the edge passes below.
fn under_edge(a: Vector, b: Vector, e0: Vector, e1: Vector) -> Option<(Real, Vector, Vector)> {
    let (dx, dz) = (b.x - a.x, b.z - a.z);
    let (ex, ez) = (e1.x - e0.x, e1.z - e0.z);
    let det = dx * ez - dz * ex;
    if det.abs() < 1.0e-12 {
        return None;
    }
    let (wx, wz) = (e0.x - a.x, e0.z - a.z);
    let u = (wx * ez - wz * ex) / det;
    let v = (wx * dz - wz * dx) / det;
    // A little past the ends too: where the axis passes under a vertex, every edge
    // through it is crossed at its end, and rounding must not lose them all.
    const SLACK: Real = 1.0e-4;
    if !(-SLACK..=1.0 + SLACK).contains(&u) || !(-SLACK..=1.0 + SLACK).contains(&v) {
        return None;
    }
    let above = (e0.y + (e1.y - e0.y) * v) - (a.y + (b.y - a.y) * u);
    if above <= 0.0 {
        return None;
    }
    let (_, on_axis, on_edge) = closest_segment_segment(a, b, e0, e1);
    Some((on_axis.distance(on_edge), on_axis, on_edge))
}

/// Squared distance between the boxes `[lo1, hi1]` and `[lo2, hi2]`: a lower bound on the
/// distance between anything inside them.
fn box_gap_sq(lo1: Vector, hi1: Vector, lo2: Vector, hi2: Vector) -> Real {
    (lo2 - hi1)
        .max(lo1 - hi2)
        .max(Vector::ZERO)
        .length_squared()
}

/// Up to three contacts of a capsule (axis `a b`, radius `r`, in the heightfield's frame)
/// with the heightfield: one per end cap and one for the axis between them, each only
/// when its gap is below `prediction` (`had_axis`: the axis had a contact last step).
/// `None` for a heightfield with removed or zigzag cells under the capsule (parry's own
/// rule handles those).
fn capsule_heightfield_probes(
    hf: &HeightField,
    a: Vector,
    b: Vector,
    r: Real,
    prediction: Real,
    had_axis: bool,
) -> Option<[Option<Probe>; 3]> {
    let reach = r + prediction;
    let reach_sq = reach * reach;
    let (lo, hi) = (a.min(b), a.max(b));
    let mut ends = [Nearest::NONE; 2];
    let mut axis = Nearest::NONE;
    // The deepest edge the axis passes under: how far it lies above the axis, and the
    // closest points of the two.
    let mut crest: (Real, Vector, Vector) = (0.0, Vector::ZERO, Vector::ZERO);
    // How much farther than the nearer end an axis contact may be and stay.
    let slack = if had_axis { 1.0e-3 } else { 0.0 };
    let (ncols, nrows) = (hf.ncols(), hf.nrows());
    let (rlo, rhi) = (lo - Vector::splat(reach), hi + Vector::splat(reach));
    if rlo.y > hf.root_aabb().maxs.y {
        // Above the highest point of the whole field (a thigh over rough ground).
        return Some([None; 3]);
    }
    if rhi.x < hf.x_at(0) || rlo.x > hf.x_at(ncols) || rhi.z < hf.z_at(0) || rlo.z > hf.z_at(nrows)
    {
        return Some([None; 3]);
    }
    let (i0, j0) = hf.closest_cell_at_point(rlo);
    let (i1, j1) = hf.closest_cell_at_point(rhi);
    let heights = hf.heights();
    let sy = hf.scale().y;
    for j in j0..=j1 {
        let (x0, x1) = (hf.x_at(j), hf.x_at(j + 1));
        for i in i0..=i1 {
            if !hf.cell_status(i, j).is_empty() {
                return None;
            }
            let (z0, z1) = (hf.z_at(i), hf.z_at(i + 1));
            let p00 = Vector::new(x0, heights[(i, j)] * sy, z0);
            let p10 = Vector::new(x0, heights[(i + 1, j)] * sy, z1);
            let p01 = Vector::new(x1, heights[(i, j + 1)] * sy, z0);
            let p11 = Vector::new(x1, heights[(i + 1, j + 1)] * sy, z1);
            let ylo = p00.y.min(p10.y).min(p01.y).min(p11.y);
            let yhi = p00.y.max(p10.y).max(p01.y).max(p11.y);
            let (clo, chi) = (Vector::new(x0, ylo, z0), Vector::new(x1, yhi, z1));
            // Skip what cannot come within reach, or nearer than the nearest found so far;
            // the axis probe only counts where it beats the nearer end (see below).
            let nearest_end_sq = ends[0].dist_sq.min(ends[1].dist_sq);
            let axis_bound = reach_sq
                .min(axis.dist_sq)
                .min(if nearest_end_sq < reach_sq {
                    (nearest_end_sq.sqrt() + slack).powi(2)
                } else {
                    reach_sq
                });
            let near_a = box_gap_sq(a, a, clo, chi) < reach_sq.min(ends[0].dist_sq);
            let near_b = box_gap_sq(b, b, clo, chi) < reach_sq.min(ends[1].dist_sq);
            let near_axis = box_gap_sq(lo, hi, clo, chi) < axis_bound;
            let may_cross = may_lie_over(lo, hi, clo, chi);
            if !(near_a || near_b || near_axis || may_cross) {
                continue;
            }
            // parry's split of a cell without flags: (p00, p10, p01) and (p10, p11, p01).
            let tris = [Triangle::new(p00, p10, p01), Triangle::new(p10, p11, p01)];
            let (n1, n2) = (up_normal(&tris[0]), up_normal(&tris[1]));
            let mut face = Vector::Y;
            for (t, n) in tris.iter().zip([n1, n2]) {
                let Some(n) = n else { continue };
                face = n;
                if near_a {
                    ends[0].offer(a, closest_on_triangle(a, t), n);
                }
                if near_b {
                    ends[1].offer(b, closest_on_triangle(b, t), n);
                }
            }
            if !(near_axis || may_cross) {
                continue;
            }
            // Above the surface, the axis comes nearest to a triangle at one of its own ends
            // (the end probes have that) or at one of the triangle's edges, and strictly
            // inside the axis only at a ridge (a convex edge: on a plane or in a valley the
            // nearest point slides to an end). Where the axis passes under the surface, it
            // passes under an edge (the surface along its path is highest at one). Each
            // cell tries the edges it owns: its diagonal, its low-x and low-z sides, and its
            // high sides on the last column and row. `opposite` is the far vertex of the
            // triangle across the edge from `plane` (a point and normal of the cell's own
            // triangle on it); `None` at the field's border.
            let vertex = |i: usize, j: usize| {
                (i <= nrows && j <= ncols)
                    .then(|| Vector::new(hf.x_at(j), heights[(i, j)] * sy, hf.z_at(i)))
            };
            let mut edge =
                |e0: Vector, e1: Vector, plane: Option<Vector>, opposite: Option<Vector>| {
                    let (elo, ehi) = (e0.min(e1), e0.max(e1));
                    if may_lie_over(lo, hi, elo, ehi) {
                        if let Some(under) = under_edge(a, b, e0, e1) {
                            if under.0 > crest.0 {
                                crest = under;
                            }
                            return;
                        }
                    }
                    let ridge = match (plane, opposite) {
                        (Some(n), Some(o)) => (o - e0).dot(n) < -1.0e-6,
                        _ => true,
                    };
                    if ridge && box_gap_sq(lo, hi, elo, ehi) < axis_bound.min(axis.dist_sq) {
                        let (s, on_axis, on_edge) = closest_segment_segment(a, b, e0, e1);
                        // Within 2% of an end the end cap carries the contact; a ridge
                        // point there must not mask one further in.
                        if s > 0.02 && s < 0.98 {
                            axis.offer(on_axis, on_edge, face);
                        }
                    }
                };
            edge(p10, p01, n1, Some(p11));
            edge(
                p00,
                p10,
                n1,
                j.checked_sub(1).and_then(|jm| vertex(i + 1, jm)),
            );
            edge(
                p00,
                p01,
                n1,
                i.checked_sub(1).and_then(|im| vertex(im, j + 1)),
            );
            if j == j1 {
                edge(p01, p11, n2, vertex(i, j + 2));
            }
            if i == i1 {
                edge(p10, p11, n2, vertex(i + 2, j));
            }
        }
    }
    let mut probes = [None; 3];
    let mut buried = false;
    for (k, (end, nearest)) in [a, b].into_iter().zip(ends.iter()).enumerate() {
        if nearest.dist_sq >= reach_sq {
            // No surface within reach (an end buried deeper than that is not looked for).
            continue;
        }
        probes[k] = match below_surface(hf, end) {
            Some((sd, n)) => {
                buried = true;
                Some(Probe {
                    dist: sd - r,
                    on_capsule: end - n * r,
                    on_terrain: end - n * sd,
                    normal: n,
                })
            }
            None => nearest.probe(r),
        };
    }
    if buried {
        // An end's own contact pushes it out; the axis is not looked at.
    } else if crest.0 > 0.0 {
        // The axis passes under the surface: out along the common normal of the axis and
        // the deepest edge above it.
        let (depth, on_axis, on_edge) = crest;
        let normal = ((on_edge - on_axis) / depth.max(1.0e-9))
            .try_normalize()
            .filter(|n| n.y > 0.0)
            .unwrap_or(Vector::Y);
        probes[2] = Some(Probe {
            dist: -depth - r,
            on_capsule: on_axis - normal * r,
            on_terrain: on_edge,
            normal,
        });
    } else {
        // A ridge under the middle adds a contact where it comes nearer to the axis than
        // either end does to the ground. Once there, it stays while it is within a
        // millimetre of the nearer end, so that a support the solver has just levelled with
        // an end is not dropped and made again.
        let nearest_end = probes[..2]
            .iter()
            .map(|p| p.map_or(Real::MAX, |p| p.dist))
            .fold(Real::MAX, Real::min);
        let keep = if had_axis { slack } else { -1.0e-4 };
        probes[2] = axis.probe(r).filter(|p| p.dist < nearest_end + keep);
    }
    for p in &mut probes {
        if p.is_some_and(|p| p.dist >= prediction) {
            *p = None;
        }
    }
    Some(probes)
}

/// The capsule's feature id of probe `k` (0, 1: the end caps, 2: the axis).
fn probe_fid(k: usize) -> PackedFeatureId {
    PackedFeatureId::vertex(k as u32)
}

/// The probe a manifold written by [`write_manifolds`] holds.
fn probe_of<M, C>(m: &ContactManifold<M, C>, flipped: bool) -> Option<PackedFeatureId> {
    m.points
        .first()
        .map(|c| if flipped { c.fid1 } else { c.fid2 })
}

/// Writes the probes as one-point manifolds between shape 1 and shape 2 of the pair,
/// keeping each probe's warm-start impulse from the previous step where rapier kept it.
fn write_manifolds<M: Default + Clone, C: Default + Copy>(
    probes: &[Option<Probe>; 3],
    capsule_in_hf: &Pose,
    flipped: bool,
    prediction: Real,
    manifolds: &mut Vec<ContactManifold<M, C>>,
) {
    // The manifolds hold last step's probes, one point each; they are reused in place
    // (no allocation while a contact persists). With more than one, rapier solved clusters
    // of them instead and their own impulses are stale: the clusters carry the warm start.
    let clustered = manifolds.len() > 1;
    let mut kept = 0;
    for (k, probe) in probes.iter().enumerate() {
        let Some(p) = probe else { continue };
        let fid_capsule = probe_fid(k);
        let fid_terrain = PackedFeatureId::face(0);
        let on_capsule = capsule_in_hf.inverse_transform_point(p.on_capsule);
        let n_capsule = capsule_in_hf.rotation.inverse() * -p.normal;
        let mut contact = if flipped {
            TrackedContact::new(on_capsule, p.on_terrain, fid_capsule, fid_terrain, p.dist)
        } else {
            TrackedContact::new(p.on_terrain, on_capsule, fid_terrain, fid_capsule, p.dist)
        };
        match manifolds[kept..]
            .iter()
            .position(|m| probe_of(m, flipped) == Some(fid_capsule))
        {
            Some(i) => manifolds.swap(kept, kept + i),
            None => manifolds.insert(kept, ContactManifold::with_data(0, 0, M::default())),
        }
        let m = &mut manifolds[kept];
        let (n_terrain, old_n_terrain) = if flipped {
            (p.normal, m.local_n2)
        } else {
            (p.normal, m.local_n1)
        };
        if let Some(old) = m.points.first().filter(|_| !clustered) {
            // The same probe's impulse warm-starts the solver while it is the same contact:
            // the terrain point within the prediction distance, the normal within 10 deg.
            let (old_terrain, new_terrain) = if flipped {
                (old.local_p2, contact.local_p2)
            } else {
                (old.local_p1, contact.local_p1)
            };
            if old_terrain.distance(new_terrain) < prediction.max(1.0e-3)
                && old_n_terrain.dot(n_terrain) > 0.985
            {
                contact.data = old.data;
            }
        }
        m.points.clear();
        if flipped {
            m.local_n1 = n_capsule;
            m.local_n2 = p.normal;
        } else {
            m.local_n1 = p.normal;
            m.local_n2 = n_capsule;
        }
        m.points.push(contact);
        kept += 1;
    }
    manifolds.truncate(kept);
}

/// Marks a pair whose manifolds [`CapsuleTerrainDispatcher`] writes. rapier rebuilds the
/// solver graph of a pair with a workspace on every full update, as for parry's
/// per-triangle manifolds; without one it would keep graph entries of manifolds that this
/// dispatcher dropped or reordered.
#[derive(Debug, Clone, Copy, Default)]
struct ProbeWorkspace;

impl WorkspaceData for ProbeWorkspace {
    fn as_typed_workspace_data(&self) -> TypedWorkspaceData<'_> {
        TypedWorkspaceData::Custom
    }

    fn clone_dyn(&self) -> Box<dyn WorkspaceData> {
        Box::new(*self)
    }
}

fn capsule_heightfield<M: Default + Clone, C: Default + Copy>(
    capsule_in_hf: &Pose,
    hf: &HeightField,
    capsule: &Capsule,
    prediction: Real,
    flipped: bool,
    manifolds: &mut Vec<ContactManifold<M, C>>,
    workspace: &mut Option<ContactManifoldsWorkspace>,
) -> Result<(), Unsupported> {
    let a = capsule_in_hf.transform_point(capsule.segment.a);
    let b = capsule_in_hf.transform_point(capsule.segment.b);
    let ours = workspace
        .as_ref()
        .is_some_and(|w| w.0.downcast_ref::<ProbeWorkspace>().is_some());
    let had_axis = ours
        && manifolds
            .iter()
            .any(|m| probe_of(m, flipped) == Some(probe_fid(2)));
    let probes = capsule_heightfield_probes(hf, a, b, capsule.radius, prediction, had_axis);
    let Some(probes) = probes else {
        // Cells with flags: parry's rule, from scratch.
        if ours {
            manifolds.clear();
            *workspace = None;
        }
        return Err(Unsupported);
    };
    if !ours {
        manifolds.clear();
        *workspace = Some(ContactManifoldsWorkspace(Box::new(ProbeWorkspace)));
    }
    write_manifolds(&probes, capsule_in_hf, flipped, prediction, manifolds);
    Ok(())
}

impl<M: Default + Clone, C: Default + Copy> PersistentQueryDispatcher<M, C>
    for CapsuleTerrainDispatcher
{
    fn contact_manifolds(
        &self,
        pos12: &Pose,
        g1: &dyn Shape,
        g2: &dyn Shape,
        prediction: Real,
        manifolds: &mut Vec<ContactManifold<M, C>>,
        workspace: &mut Option<ContactManifoldsWorkspace>,
    ) -> Result<(), Unsupported> {
        if let (Some(hf), Some(c)) = (g1.as_heightfield(), g2.as_capsule()) {
            capsule_heightfield(pos12, hf, c, prediction, false, manifolds, workspace)
        } else if let (Some(c), Some(hf)) = (g1.as_capsule(), g2.as_heightfield()) {
            capsule_heightfield(
                &pos12.inverse(),
                hf,
                c,
                prediction,
                true,
                manifolds,
                workspace,
            )
        } else {
            Err(Unsupported)
        }
    }

    fn contact_manifold_convex_convex(
        &self,
        _pos12: &Pose,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
        _normal_constraints1: Option<&dyn NormalConstraints>,
        _normal_constraints2: Option<&dyn NormalConstraints>,
        _prediction: Real,
        _manifold: &mut ContactManifold<M, C>,
    ) -> Result<(), Unsupported> {
        Err(Unsupported)
    }
}

impl QueryDispatcher for CapsuleTerrainDispatcher {
    fn intersection_test(
        &self,
        _pos12: &Pose,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
    ) -> Result<ShapeIntersection, Unsupported> {
        Err(Unsupported)
    }

    fn distance(
        &self,
        _pos12: &Pose,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
    ) -> Result<ShapeDistance, Unsupported> {
        Err(Unsupported)
    }

    fn contact(
        &self,
        _pos12: &Pose,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
        _prediction: Real,
    ) -> Result<Option<Contact>, Unsupported> {
        Err(Unsupported)
    }

    fn closest_points(
        &self,
        _pos12: &Pose,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
        _max_dist: Real,
    ) -> Result<ClosestPoints, Unsupported> {
        Err(Unsupported)
    }

    fn cast_shapes(
        &self,
        _pos12: &Pose,
        _local_vel12: Vector,
        _g1: &dyn Shape,
        _g2: &dyn Shape,
        _options: ShapeCastOptions,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        Err(Unsupported)
    }

    fn cast_shapes_nonlinear(
        &self,
        _motion1: &NonlinearRigidMotion,
        _g1: &dyn Shape,
        _motion2: &NonlinearRigidMotion,
        _g2: &dyn Shape,
        _start_time: Real,
        _end_time: Real,
        _stop_at_penetration: bool,
    ) -> Result<Option<ShapeCastHit>, Unsupported> {
        Err(Unsupported)
    }
}

#[cfg(test)]
#[path = "contact_tests.rs"]
mod tests;
