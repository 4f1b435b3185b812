use super::*;
use rand::{Rng, SeedableRng};
use rapier3d::parry::bounding_volume::{Aabb, BoundingVolume};
use rapier3d::parry::query;
use rapier3d::parry::utils::Array2;

/// A 2 m x 2 m heightfield of `n` x `n` cells, heights from `h(x, z)`.
fn field(n: usize, h: impl Fn(Real, Real) -> Real) -> HeightField {
    let heights = Array2::from_fn(n + 1, n + 1, |i, j| {
        h(
            j as Real * 2.0 / n as Real - 1.0,
            i as Real * 2.0 / n as Real - 1.0,
        )
    });
    HeightField::new(heights, Vector::new(2.0, 1.0, 2.0))
}

fn probes(hf: &HeightField, a: Vector, b: Vector, r: Real) -> Vec<Probe> {
    capsule_heightfield_probes(hf, a, b, r, 0.05, false)
        .unwrap()
        .into_iter()
        .flatten()
        .collect()
}

#[test]
fn a_capsule_lying_on_flat_ground_rests_on_both_ends() {
    let hf = field(20, |_, _| 0.0);
    let p = probes(
        &hf,
        Vector::new(-0.2, 0.04, 0.03),
        Vector::new(0.2, 0.04, 0.03),
        0.03,
    );
    assert_eq!(p.len(), 2, "{p:?}");
    for c in &p {
        assert!((c.dist - 0.01).abs() < 1e-5, "{c:?}");
        assert!((c.normal - Vector::Y).length() < 1e-5, "{c:?}");
    }
}

/// On a plane the gap along a tilted axis grows from its lower end: the contacts are
/// under the end caps, whatever the tilt and heading (none at an edge of the
/// triangulation).
#[test]
fn a_tilted_capsule_on_flat_ground_touches_at_its_ends_only() {
    let hf = field(20, |_, _| 0.0);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..2000 {
        let heading: Real = rng.random_range(0.0..std::f32::consts::TAU);
        let tilt: Real = rng.random_range(0.001..0.3);
        let dir = Vector::new(
            heading.cos() * tilt.cos(),
            tilt.sin(),
            heading.sin() * tilt.cos(),
        );
        let a = Vector::new(
            rng.random_range(-0.3..0.3),
            0.035,
            rng.random_range(-0.3..0.3),
        );
        let b = a + dir * 0.35;
        let p = probes(&hf, a, b, 0.03);
        assert!(!p.is_empty());
        for c in &p {
            // Under an end cap's centre, straight up (the upper end may be within the
            // prediction distance too).
            let under = |e: Vector| (c.on_terrain - Vector::new(e.x, 0.0, e.z)).length() < 1e-4;
            assert!(under(a) || under(b), "tilt {tilt} heading {heading}: {p:?}");
            assert!((c.normal - Vector::Y).length() < 1e-3, "{p:?}");
        }
    }
}

#[test]
fn a_capsule_across_a_ridge_rests_on_the_ridge() {
    // A ridge along z at x = 0, 10 cm high, falling to 0 at |x| = 0.1.
    let hf = field(20, |x, _| (0.1 - x.abs()).max(0.0));
    let p = probes(
        &hf,
        Vector::new(-0.3, 0.12, 0.0),
        Vector::new(0.3, 0.12, 0.0),
        0.03,
    );
    assert_eq!(p.len(), 1, "{p:?}");
    assert!((p[0].dist - (-0.01)).abs() < 1e-5, "{p:?}");
    assert!(p[0].on_terrain.x.abs() < 1e-5 && (p[0].on_terrain.y - 0.1).abs() < 1e-5);
}

#[test]
fn an_axis_under_a_ridge_is_pushed_up_over_it_whichever_way_it_points() {
    // The ridge of the previous test, 1 cm above the axis; both ends clear the ground.
    let hf = field(20, |x, _| (0.1 - x.abs()).max(0.0));
    let (a, b) = (Vector::new(-0.3, 0.09, 0.0), Vector::new(0.3, 0.09, 0.0));
    for (a, b) in [(a, b), (b, a)] {
        let p = probes(&hf, a, b, 0.03);
        assert_eq!(p.len(), 1, "{p:?}");
        assert!((p[0].dist - (-0.04)).abs() < 1e-5, "{p:?}");
        assert!((p[0].normal - Vector::Y).length() < 1e-4, "{p:?}");
    }
}

/// Through the dispatcher, with the heightfield as either shape of the pair: the same
/// contacts in the world, normals from shape 1 to shape 2, manifolds reused in place.
#[test]
fn both_pair_orders_give_the_same_contacts() {
    type Manifold = ContactManifold<(), ()>;
    let hf = field(20, |x, _| (0.1 - x.abs()).max(0.0));
    let capsule = Capsule::new(
        Vector::new(-0.3, 0.0, 0.0),
        Vector::new(0.3, 0.0, 0.0),
        0.03,
    );
    let capsule_pose = Pose::from_parts(
        Vector::new(0.05, 0.125, 0.2),
        rapier3d::math::Rotation::from_rotation_y(0.3),
    );
    let d = CapsuleTerrainDispatcher;
    let (mut m12, mut w12) = (Vec::<Manifold>::new(), None);
    let (mut m21, mut w21) = (Vec::<Manifold>::new(), None);
    for _ in 0..2 {
        d.contact_manifolds(&capsule_pose, &hf, &capsule, 0.02, &mut m12, &mut w12)
            .unwrap();
        d.contact_manifolds(
            &capsule_pose.inverse(),
            &capsule,
            &hf,
            0.02,
            &mut m21,
            &mut w21,
        )
        .unwrap();
    }
    assert!(w12.is_some() && w21.is_some());
    assert_eq!(m12.len(), 1, "the ridge under the middle");
    assert_eq!(m21.len(), 1);
    let (c12, c21) = (m12[0].points[0], m21[0].points[0]);
    assert!((c12.dist - c21.dist).abs() < 1e-6 && c12.dist < 0.0);
    // World = the heightfield's frame here.
    let (terrain12, terrain21) = (c12.local_p1, c21.local_p2);
    let (capsule12, capsule21) = (
        capsule_pose.transform_point(c12.local_p2),
        capsule_pose.transform_point(c21.local_p1),
    );
    assert!(terrain12.distance(terrain21) < 1e-5 && capsule12.distance(capsule21) < 1e-5);
    let n12 = m12[0].local_n1;
    let n21 = capsule_pose.rotation * m21[0].local_n1;
    assert!((n12 + n21).length() < 1e-5 && n12.y > 0.9, "{n12} {n21}");
    assert!((capsule12 - terrain12).dot(n12) - c12.dist < 1e-5);
}

#[test]
fn a_buried_end_is_pushed_out_of_the_ground() {
    let hf = field(20, |_, _| 0.0);
    let p = probes(
        &hf,
        Vector::new(-0.2, -0.05, 0.0),
        Vector::new(0.2, 0.2, 0.0),
        0.03,
    );
    assert_eq!(p.len(), 1, "{p:?}");
    assert!((p[0].dist - (-0.08)).abs() < 1e-5, "{p:?}");
    assert!((p[0].normal - Vector::Y).length() < 1e-5);
}

/// On random rough ground and random capsule poses, the deepest probe is the distance
/// between the capsule and the heightfield: the closed form finds the nearest
/// surface point wherever it lies (face, edge or vertex; end cap or axis).
#[test]
fn the_nearest_probe_is_the_capsules_distance_to_the_ground() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let heights: Vec<Real> = (0..21 * 21).map(|_| rng.random_range(0.0..0.08)).collect();
    let hf = field(20, |x, z| {
        let j = ((x + 1.0) * 10.0).round() as usize;
        let i = ((z + 1.0) * 10.0).round() as usize;
        heights[i * 21 + j]
    });
    let (mut checked, mut exact_ones) = (0, 0);
    for _ in 0..2000 {
        let c = Vector::new(
            rng.random_range(-0.5..0.5),
            rng.random_range(0.05..0.2),
            rng.random_range(-0.5..0.5),
        );
        let d = Vector::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
            * 0.15;
        let (a, b, r) = (c - d, c + d, 0.03);
        let capsule = Capsule::new(a, b, r);
        // The reference: parry's distance to every triangle (GJK), and, near the
        // ground, a dense sampling of the axis with parry's exact point projection.
        let around = Aabb::new(a.min(b), a.max(b)).loosened(0.1);
        let mut exact = Real::MAX;
        hf.map_elements_in_local_aabb(&around, &mut |_, t| {
            let d = query::distance(&Pose::IDENTITY, t, &Pose::IDENTITY, &capsule).unwrap();
            exact = exact.min(d.distance);
        });
        if exact <= 0.0 || exact > 0.04 {
            continue;
        }
        hf.map_elements_in_local_aabb(&around, &mut |_, t| {
            for k in 0..=300 {
                let p = a + (b - a) * (k as Real / 300.0);
                // parry's GJK can stop short of the minimum by up to ~1 mm in f32.
                exact = exact.min(p.distance(t.project_local_point(p, true).point) - r);
            }
        });
        let p = probes(&hf, a, b, r);
        let nearest = p.iter().map(|p| p.dist).fold(Real::MAX, Real::min);
        // Exact, but where the axis comes nearest within 2% of an end the end cap
        // carries the contact (a fraction of a millimetre farther).
        assert!(
            nearest >= exact - 2e-4 && nearest <= exact + 1e-3,
            "{nearest} vs {exact} for {a} {b}"
        );
        if nearest <= exact + 1e-5 {
            exact_ones += 1;
        }
        for q in &p {
            // Each contact's points are `dist` apart along its normal.
            let gap = (q.on_capsule - q.on_terrain).dot(q.normal);
            assert!((gap - q.dist).abs() < 1e-4, "{q:?}");
        }
        checked += 1;
    }
    assert!(checked > 100, "only {checked} poses near the ground");
    assert!(
        exact_ones * 10 >= checked * 9,
        "{exact_ones} of {checked} exact"
    );
}

/// On a staircase (10 cm steps, 30 cm treads, risers as 45-degree ramps between grid
/// samples, as the stairs terrain is) the closed form gives the solver what parry's
/// per-triangle manifolds give it for shanks and the base 0-2 cm in the surface: the same
/// deepest penetration and the same direction of the depth-weighted push. And it adds
/// none of parry's internal-edge normals: the steps vary along x only, so every true
/// contact normal lies in the x-y plane, while parry's manifolds hold one tilted sideways
/// (|n_z| > 0.05, off a triangle's diagonal or side) in most of this test's poses, 2 cm
/// in to 2 mm off the surface (printed with `--nocapture`).
#[test]
fn on_stairs_the_solver_gets_what_parrys_manifolds_give_it() {
    type Manifold = ContactManifold<(), ()>;
    use rapier3d::parry::query::DefaultQueryDispatcher;
    let step = |x: Real| ((x + 1.0) / 0.3).floor().max(0.0) * 0.1;
    let hf = field(20, |x, _| step(x));
    // Signed distance of a point to the surface (negative inside the ground).
    let signed = |p: Vector| {
        let around = Aabb::new(p, p).loosened(0.15);
        let mut d = Real::MAX;
        hf.map_elements_in_local_aabb(&around, &mut |_, t| {
            d = d.min(p.distance(t.project_local_point(p, false).point));
        });
        if below_surface(&hf, p).is_some() {
            -d
        } else {
            d
        }
    };
    for (name, r, half) in [("shank", 0.03, 0.095), ("base", 0.1, 0.375)] {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let capsule = Capsule::new(Vector::new(0.0, -half, 0.0), Vector::new(0.0, half, 0.0), r);
        let (mut n, mut pen, mut apart, mut depth_diff) = (0, 0, 0, 0.0);
        let mut parry_tilted = 0;
        while n < 400 {
            let cx: Real = rng.random_range(-0.6..0.6);
            let c = Vector::new(
                cx,
                step(cx) + rng.random_range(-0.05..(half + r)),
                rng.random_range(-0.3..0.3),
            );
            let axis = Vector::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let pose = Pose::from_parts(
                c,
                rapier3d::math::Rotation::from_rotation_arc(Vector::Y, axis),
            );
            let (a, b) = (
                pose.transform_point(capsule.segment.a),
                pose.transform_point(capsule.segment.b),
            );
            let exact = (0..=40)
                .map(|k| signed(a + (b - a) * (k as Real / 40.0)) - r)
                .fold(Real::MAX, Real::min);
            if !(-0.02..0.002).contains(&exact) {
                continue;
            }
            n += 1;
            let mut push = [Vector::ZERO; 2];
            let mut deepest: [Real; 2] = [0.0; 2];
            let mut tilted = false;
            for (k, closed_form) in [false, true].into_iter().enumerate() {
                let (mut m, mut w) = (Vec::<Manifold>::new(), None);
                if closed_form {
                    CapsuleTerrainDispatcher
                        .contact_manifolds(&pose, &hf, &capsule, 0.002, &mut m, &mut w)
                } else {
                    DefaultQueryDispatcher
                        .contact_manifolds(&pose, &hf, &capsule, 0.002, &mut m, &mut w)
                }
                .unwrap();
                for mf in &m {
                    for pt in mf.points.iter().filter(|pt| pt.dist < 0.002) {
                        if closed_form {
                            assert!(mf.local_n1.z.abs() < 1.0e-4, "{name}: {}", mf.local_n1);
                        } else {
                            tilted |= mf.local_n1.z.abs() > 0.05;
                        }
                        if exact < 0.0 {
                            push[k] += mf.local_n1 * (-pt.dist).max(0.0);
                            deepest[k] = deepest[k].min(pt.dist);
                        }
                    }
                }
            }
            parry_tilted += usize::from(tilted);
            if exact >= 0.0 {
                continue;
            }
            pen += 1;
            depth_diff += (deepest[1] - deepest[0]).abs();
            let (p0, p1) = (push[0].normalize_or_zero(), push[1].normalize_or_zero());
            if p0.dot(p1) < 0.866 {
                apart += 1;
            }
        }
        assert!(pen > 100, "{name}: only {pen} of {n} poses penetrate");
        let depth_diff = depth_diff / pen as Real;
        // What the comparison found, and what parry's manifolds add (BENCHMARKS.md).
        eprintln!(
            "{name}: {n} poses, {pen} penetrating: deepest differs by {depth_diff} m on average, \
             {apart} pushes more than 30 degrees apart; parry tilted a normal sideways in \
             {parry_tilted} of the {n}"
        );
        assert!(
            depth_diff < 1.0e-3,
            "{name}: mean deepest differs by {depth_diff}"
        );
        assert!(
            apart * 100 <= pen * 4,
            "{name}: {apart} of {pen} pushes more than 30 degrees apart"
        );
    }
}
