//! The left-right mirror of observations and actions, for rsl_rl's symmetry loss and its
//! mirrored samples (data augmentation).
//!
//! Mirroring the robot in its sagittal plane (base frame y -> -y) maps a state to the state
//! of the mirrored robot: polar vectors (linear velocity, gravity) flip their y component,
//! axial vectors (angular velocity, the commanded yaw rate) flip x and z, the joints trade
//! places left for right (the preset's `mirror` map, hip abduction changing sign) and the
//! height scan is read from the other side. A policy that walks left as it walks right maps
//! the mirrored observation to the mirrored action.

use crate::agent::NJ;
use crate::preset::Preset;

/// An index map with signs: `out[k] = sign_k * in[src_k]` for entry `k = (src_k, sign_k)`.
pub type SignedMap = Vec<(usize, f32)>;

/// The mirror of one preset's observation and action layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Mirror {
    /// The observation map (`obs_dim` entries).
    pub obs: SignedMap,
    /// The action map (one entry per joint).
    pub act: SignedMap,
}

/// Reads a preset's `mirror` list (entry k: `[-]JOINT`, the joint whose value the mirrored
/// robot's joint k takes) against its joints. Empty when the list is; an error (the
/// preset problem, in words) unless it names each joint once and undoes itself.
pub fn joint_map(joints: &[String], mirror: &[String]) -> std::result::Result<SignedMap, String> {
    if mirror.is_empty() {
        return Ok(Vec::new());
    }
    if mirror.len() != joints.len() {
        return Err(format!(
            "mirror: expected {} entries (one per joint), found {}",
            joints.len(),
            mirror.len()
        ));
    }
    let mut map = Vec::with_capacity(mirror.len());
    for entry in mirror {
        let (sign, name) = match entry.strip_prefix('-') {
            Some(name) => (-1.0, name),
            None => (1.0, entry.as_str()),
        };
        let Some(src) = joints.iter().position(|j| j == name) else {
            return Err(format!(
                "mirror: {name:?} is not one of the joints {joints:?}; write each joint's mirror \
                 image, with a leading '-' where the angle changes sign"
            ));
        };
        map.push((src, sign));
    }
    for (k, &(src, sign)) in map.iter().enumerate() {
        if map[src] != (k, sign) {
            return Err(format!(
                "mirror: {} maps to {} but {} does not map back to {} with the same sign; a \
                 mirror must undo itself",
                joints[k], joints[src], joints[src], joints[k]
            ));
        }
    }
    Ok(map)
}

impl Mirror {
    /// The mirror of `preset`'s observations (as `preset.obs_dim()` lays them out: the 48
    /// proprioceptive values, then the height scan with `scan_y` inner) and actions. `None`
    /// when the preset names no joint mirror; an error when its mirror is not one of its
    /// joints (e.g. inherited from the preset it is based on) or the scan is not symmetric.
    pub fn for_preset(preset: &Preset) -> std::result::Result<Option<Mirror>, String> {
        if preset.mirror.is_empty() {
            return Ok(None);
        }
        let joints = joint_map(&preset.joints, &preset.mirror)?;
        let mut obs: SignedMap = Vec::with_capacity(preset.obs_dim());
        let vector = |obs: &mut SignedMap, at: usize, signs: [f32; 3]| {
            obs.extend(signs.iter().enumerate().map(|(i, &s)| (at + i, s)));
        };
        vector(&mut obs, 0, [1.0, -1.0, 1.0]); // base linear velocity
        vector(&mut obs, 3, [-1.0, 1.0, -1.0]); // base angular velocity
        vector(&mut obs, 6, [1.0, -1.0, 1.0]); // projected gravity
        vector(&mut obs, 9, [1.0, -1.0, -1.0]); // commands: forward, lateral, yaw rate
        for block in [12, 12 + NJ, 12 + 2 * NJ] {
            // joint positions, velocities, last actions
            obs.extend(joints.iter().map(|&(src, s)| (block + src, s)));
        }
        let (xs, ys) = (&preset.observation.scan_x, &preset.observation.scan_y);
        let ny = ys.len();
        if (0..ny).any(|j| (ys[j] + ys[ny - 1 - j]).abs() > 1e-6) {
            return Err(format!(
                "observation.scan_y {ys:?} is not symmetric about 0, so the height scan has no \
                 mirror image; use symmetric points or leave mirror empty"
            ));
        }
        let scan = 12 + 3 * NJ;
        for i in 0..xs.len() {
            obs.extend((0..ny).map(|j| (scan + i * ny + (ny - 1 - j), 1.0)));
        }
        debug_assert_eq!(obs.len(), preset.obs_dim());
        Ok(Some(Mirror { obs, act: joints }))
    }

    /// Applies a map to one row.
    pub fn apply(map: &[(usize, f32)], row: &[f32]) -> Vec<f32> {
        map.iter().map(|&(src, s)| s * row[src]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn joint_maps_must_name_every_joint_and_undo_themselves() {
        let joints = names(&["L_A", "L_B", "R_A", "R_B"]);
        let m = joint_map(&joints, &names(&["-R_A", "R_B", "-L_A", "L_B"])).unwrap();
        assert_eq!(m, vec![(2, -1.0), (3, 1.0), (0, -1.0), (1, 1.0)]);
        assert!(joint_map(&joints, &[]).unwrap().is_empty());
        let e = joint_map(&joints, &names(&["R_A", "R_B", "L_A"])).unwrap_err();
        assert!(e.contains("expected 4 entries"), "{e}");
        let e = joint_map(&joints, &names(&["-R_A", "R_B", "-L_X", "L_B"])).unwrap_err();
        assert!(e.contains("\"L_X\" is not one of the joints"), "{e}");
        // R_A's sign differs from L_A's: not a mirror.
        let e = joint_map(&joints, &names(&["-R_A", "R_B", "L_A", "L_B"])).unwrap_err();
        assert!(e.contains("does not map back"), "{e}");
    }

    #[test]
    fn the_shipped_presets_mirror_their_observations_and_actions() {
        for robot in ["anymal", "heavy"] {
            let base = Preset::load(robot).unwrap();
            for terrain in [crate::TerrainKind::Flat, crate::TerrainKind::Stairs] {
                let p = base.for_terrain(terrain);
                let m = Mirror::for_preset(&p)
                    .unwrap()
                    .expect("the preset names a mirror");
                assert_eq!(m.obs.len(), p.obs_dim());
                // A mirror applied twice is the identity, on both maps.
                let row: Vec<f32> = (0..p.obs_dim()).map(|i| i as f32 + 1.0).collect();
                let twice = Mirror::apply(&m.obs, &Mirror::apply(&m.obs, &row));
                assert_eq!(twice, row, "{robot} {terrain}");
                let a: Vec<f32> = (0..NJ).map(|i| i as f32 + 1.0).collect();
                assert_eq!(Mirror::apply(&m.act, &Mirror::apply(&m.act, &a)), a);
                // Left front hip abduction becomes minus the right front one.
                let lf = p.joints.iter().position(|j| j == "LF_HAA").unwrap();
                let rf = p.joints.iter().position(|j| j == "RF_HAA").unwrap();
                assert_eq!(m.act[lf], (rf, -1.0));
                // The lateral velocity and the yaw rate flip; forward speed does not.
                let o = Mirror::apply(&m.obs, &row);
                assert_eq!(
                    (o[0], o[1], o[5], o[9], o[11]),
                    (1.0, -2.0, -6.0, 10.0, -12.0)
                );
                if terrain == crate::TerrainKind::Stairs {
                    // The first scan point (rightmost, rearmost) reads the leftmost one.
                    let ny = p.observation.scan_y.len();
                    assert_eq!(o[48], row[48 + ny - 1]);
                }
            }
        }
    }
}
