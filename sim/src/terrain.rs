//! Terrains of legged_gym: flat, rough (random heightfield), stairs (up and down) and
//! slopes, at difficulty levels 0..=9, with legged_gym's curriculum rule.
//!
//! Every robot lives in its own world on one square tile made of 3 x 3 sub-tiles of
//! [`SUB_TILE`] metres of the same level; it spawns in the middle of the centre sub-tile.
//! Every kind repeats every [`SUB_TILE`] metres, so a robot that walks more than one
//! sub-tile from the centre is moved back by one period without feeling it (the agent does
//! this): the ground is unbounded and no episode ends at an edge. Tiles are generated once
//! per (kind, level, variant), heightfield included, and shared by every world; training
//! and evaluation draw their random fields from disjoint seeds ([`TerrainUse`]).

use std::fmt;
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Side of one legged_gym sub-tile (m).
pub const SUB_TILE: f32 = 8.0;
/// Side of the tile a robot lives on (m).
pub const TILE: f32 = 3.0 * SUB_TILE;
/// Horizontal resolution of the heightfield (m), legged_gym's `horizontal_scale`.
pub const HORIZONTAL_SCALE: f32 = 0.1;
/// Number of difficulty levels (legged_gym's `num_rows`).
pub const LEVELS: u8 = 10;
/// legged_gym's platform in the middle of stairs and slopes (m).
const PLATFORM: f32 = 3.0;

pub use gaitsweep_model::TerrainKind;

/// legged_gym's terrain parameters at a difficulty level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelParams {
    /// difficulty = level / LEVELS, in [0, 0.9].
    pub difficulty: f32,
    /// Slope (rise over run) of pyramid slopes: 0.4 * difficulty.
    pub slope: f32,
    /// Stair height (m): 0.05 + 0.18 * difficulty.
    pub step_height: f32,
    /// Stair width (m).
    pub step_width: f32,
    /// Half range of the random heights of rough terrain (m).
    pub roughness: f32,
}

impl LevelParams {
    /// The parameters of a level (clamped to 0..LEVELS).
    pub fn at(level: u8) -> LevelParams {
        let difficulty = level.min(LEVELS - 1) as f32 / LEVELS as f32;
        LevelParams {
            difficulty,
            slope: 0.4 * difficulty,
            step_height: 0.05 + 0.18 * difficulty,
            step_width: 0.31,
            roughness: 0.02 + 0.1 * difficulty,
        }
    }
}

/// legged_gym's curriculum: move up a level after walking farther than half a sub-tile,
/// down after covering less than half the commanded distance; stay within 0..LEVELS. A
/// robot that walks out of the last level goes to `after_last()` (legged_gym: a random level).
pub fn curriculum_update(
    level: u8,
    walked: f32,
    commanded: f32,
    after_last: impl FnOnce() -> u8,
) -> u8 {
    if walked > SUB_TILE / 2.0 {
        if level + 1 >= LEVELS {
            after_last().min(LEVELS - 1)
        } else {
            level + 1
        }
    } else if walked < commanded * 0.5 {
        level.saturating_sub(1)
    } else {
        level
    }
}

/// A square heightfield centred on the origin, heights in metres.
#[derive(Debug, Clone)]
pub struct HeightGrid {
    /// Samples per side.
    pub n: usize,
    /// Spacing (m).
    pub scale: f32,
    /// Heights, `h[ix * n + iy]`, x = (ix - (n-1)/2) * scale.
    pub h: Vec<f32>,
}

impl HeightGrid {
    /// A grid of `side` metres at `scale` filled by `f(x, y)`.
    pub fn from_fn(side: f32, scale: f32, f: impl Fn(f32, f32) -> f32) -> HeightGrid {
        let n = (side / scale).round() as usize + 1;
        let half = (n - 1) as f32 / 2.0;
        let mut h = Vec::with_capacity(n * n);
        for ix in 0..n {
            for iy in 0..n {
                h.push(f((ix as f32 - half) * scale, (iy as f32 - half) * scale));
            }
        }
        HeightGrid { n, scale, h }
    }

    /// Side length (m).
    pub fn side(&self) -> f32 {
        (self.n - 1) as f32 * self.scale
    }

    /// Bilinear height at (x, y); outside the grid, the nearest edge.
    pub fn height(&self, x: f32, y: f32) -> f32 {
        let half = (self.n - 1) as f32 / 2.0;
        let max = (self.n - 1) as f32;
        let fx = (x / self.scale + half).clamp(0.0, max);
        let fy = (y / self.scale + half).clamp(0.0, max);
        let (ix, iy) = (
            (fx.floor() as usize).min(self.n - 2),
            (fy.floor() as usize).min(self.n - 2),
        );
        let (tx, ty) = (fx - ix as f32, fy - iy as f32);
        let at = |a: usize, b: usize| self.h[a * self.n + b];
        let h0 = at(ix, iy) * (1.0 - ty) + at(ix, iy + 1) * ty;
        let h1 = at(ix + 1, iy) * (1.0 - ty) + at(ix + 1, iy + 1) * ty;
        h0 * (1.0 - tx) + h1 * tx
    }
}

/// One generated tile.
pub struct Tile {
    /// Kind of terrain.
    pub kind: TerrainKind,
    /// Difficulty level.
    pub level: u8,
    /// The heights; `None` for flat ground (a plane at z = 0).
    pub grid: Option<HeightGrid>,
    /// The heightfield collider shape built from `grid` (shared by every world on the tile),
    /// in parry's frame: local y up, turned to world z by the collider's rotation.
    pub collider: Option<rapier3d::prelude::SharedShape>,
}

impl fmt::Debug for Tile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Tile")
            .field("kind", &self.kind)
            .field("level", &self.level)
            .field("n", &self.grid.as_ref().map(|g| g.n))
            .finish()
    }
}

/// Which random fields a terrain set draws: training and evaluation use disjoint seeds, so
/// that a score measures walking on ground the policy has not seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TerrainUse {
    /// Training tiles (variants 0 and 1; mixed: 0..20).
    Train,
    /// Evaluation tiles (variants 2 and 3; mixed: 20..40).
    Eval,
}

fn heightfield(g: &HeightGrid) -> rapier3d::prelude::SharedShape {
    // parry's heightfield lies in its local xz plane with y up; the collider turns it so
    // that local y is world z. Row i then runs along world -y.
    let n = g.n;
    let heights = rapier3d::parry::utils::Array2::from_fn(n, n, |i, j| g.h[j * n + (n - 1 - i)]);
    let side = g.side();
    rapier3d::prelude::SharedShape::heightfield(
        heights,
        rapier3d::math::Vector::new(side, 1.0, side),
    )
}

impl Tile {
    /// A tile of these heights (`None`: flat ground), its collider built once.
    pub fn new(kind: TerrainKind, level: u8, grid: Option<HeightGrid>) -> Tile {
        let collider = grid.as_ref().map(heightfield);
        Tile {
            kind,
            level,
            grid,
            collider,
        }
    }

    /// Terrain height at (x, y).
    pub fn height(&self, x: f32, y: f32) -> f32 {
        self.grid.as_ref().map_or(0.0, |g| g.height(x, y))
    }
}

/// Position inside the 8 m sub-tile, centred: in [-4, 4).
pub(crate) fn sub(v: f32) -> f32 {
    (v + SUB_TILE / 2.0).rem_euclid(SUB_TILE) - SUB_TILE / 2.0
}

/// The tiles of the mixed terrain, dealt to robots in turn: legged_gym's proportions
/// (smooth slope 0.1, rough slope 0.1, stairs up 0.35, stairs down 0.25, discrete
/// obstacles 0.2) over the kinds built here, in 20 tiles: a slope up and one down (0.1),
/// six rough fields (0.3: legged_gym's rough slope and discrete obstacles, the kinds of
/// uneven ground we have no separate generator for), seven stairs up (0.35) and five down
/// (0.25). Each entry: kind and its up (0) or down (1) variant.
pub const MIXED: [(TerrainKind, u32); 20] = {
    use TerrainKind::{Rough as R, Slopes as P, Stairs as S};
    [
        (P, 0),
        (P, 1),
        (R, 0),
        (S, 0),
        (S, 1),
        (S, 0),
        (R, 0),
        (S, 1),
        (S, 0),
        (R, 0),
        (S, 1),
        (S, 0),
        (R, 0),
        (S, 1),
        (S, 0),
        (R, 0),
        (S, 1),
        (S, 0),
        (R, 0),
        (S, 0),
    ]
};

/// The name of each [`MIXED`] tile by its kind (robots on tiles of one name are counted
/// together in the curriculum's per-variant levels).
pub static MIXED_NAMES: [&str; 20] = {
    let mut names = [""; 20];
    let mut k = 0;
    while k < 20 {
        names[k] = match MIXED[k] {
            (TerrainKind::Slopes, 0) => "slope_up",
            (TerrainKind::Slopes, _) => "slope_down",
            (TerrainKind::Stairs, 0) => "stairs_up",
            (TerrainKind::Stairs, _) => "stairs_down",
            _ => "rough",
        };
        k += 1;
    }
    names
};

/// Generates the tile of a kind at a level; `variant` picks up (even) or down (odd) for
/// stairs and slopes, and the random field of rough terrain; for the mixed terrain it picks
/// the [`MIXED`] entry `variant % 20` (its rough fields seeded apart from rough's own).
pub fn generate(kind: TerrainKind, level: u8, variant: u32) -> Tile {
    if kind == TerrainKind::Mixed {
        let (sub, up_down) = MIXED[variant as usize % MIXED.len()];
        let v = match sub {
            TerrainKind::Rough => 0x1000 + variant,
            _ => up_down,
        };
        let t = generate(sub, level, v);
        return Tile::new(TerrainKind::Mixed, level, t.grid);
    }
    let p = LevelParams::at(level);
    let sign = if variant.is_multiple_of(2) { 1.0 } else { -1.0 };
    let grid = match kind {
        TerrainKind::Flat => None,
        TerrainKind::Mixed => unreachable!("mixed tiles are made of the other kinds above"),
        TerrainKind::Rough => {
            // legged_gym: uniform noise on a coarser grid (downsampled_scale 0.2 m), upsampled;
            // here one period of SUB_TILE metres repeated over the tile.
            let mut rng =
                ChaCha8Rng::seed_from_u64(0x7e11a1 ^ ((level as u64) << 8) ^ variant as u64);
            let per = (SUB_TILE / 0.2).round() as usize;
            let period: Vec<f32> = (0..per * per)
                .map(|_| rng.random_range(-p.roughness..=p.roughness))
                .collect();
            let reps = (TILE / SUB_TILE).round() as usize;
            let n = per * reps + 1;
            let coarse = HeightGrid {
                n,
                scale: 0.2,
                h: (0..n * n)
                    .map(|k| period[(k / n) % per * per + (k % n) % per])
                    .collect(),
            };
            let mut g = HeightGrid::from_fn(TILE, HORIZONTAL_SCALE, |x, y| coarse.height(x, y));
            // Quantise like legged_gym's vertical_scale (5 mm).
            for h in &mut g.h {
                *h = (*h / 0.005).round() * 0.005;
            }
            Some(g)
        }
        TerrainKind::Stairs => Some(HeightGrid::from_fn(TILE, HORIZONTAL_SCALE, |x, y| {
            // Pyramid stairs: one step per step_width from the sub-tile edge to the platform.
            let d = (SUB_TILE / 2.0 - sub(x).abs()).min(SUB_TILE / 2.0 - sub(y).abs());
            let steps = (d / p.step_width)
                .floor()
                .min(((SUB_TILE - PLATFORM) / 2.0 / p.step_width).floor());
            sign * steps * p.step_height
        })),
        TerrainKind::Slopes => Some(HeightGrid::from_fn(TILE, HORIZONTAL_SCALE, |x, y| {
            let d = (SUB_TILE / 2.0 - sub(x).abs()).min(SUB_TILE / 2.0 - sub(y).abs());
            sign * d.min((SUB_TILE - PLATFORM) / 2.0) * p.slope
        })),
    };
    Tile::new(kind, level, grid)
}

/// Every tile of a kind, by level and variant, generated once and shared.
#[derive(Debug, Clone)]
pub struct TerrainSet {
    /// `tiles[level][variant]`.
    pub tiles: Vec<Vec<Arc<Tile>>>,
}

impl TerrainSet {
    /// Generates the tiles of `kind` (two variants: up/down, or two random fields) for
    /// training or for evaluation (random fields from disjoint seeds).
    pub fn new(kind: TerrainKind, usage: TerrainUse) -> TerrainSet {
        let variants = match kind {
            TerrainKind::Flat => 1,
            TerrainKind::Mixed => MIXED.len() as u32,
            _ => 2,
        };
        let first = match usage {
            TerrainUse::Train => 0,
            TerrainUse::Eval => variants,
        };
        TerrainSet {
            tiles: (0..LEVELS)
                .map(|l| {
                    (first..first + variants)
                        .map(|v| Arc::new(generate(kind, l, v)))
                        .collect()
                })
                .collect(),
        }
    }

    /// The tile of a robot at a level.
    pub fn tile(&self, level: u8, robot: usize) -> &Arc<Tile> {
        let row = &self.tiles[level.min(LEVELS - 1) as usize];
        &row[robot % row.len()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_follow_legged_gym() {
        let p = LevelParams::at(5);
        assert!((p.step_height - (0.05 + 0.18 * 0.5)).abs() < 1e-6);
        assert!((p.slope - 0.2).abs() < 1e-6);
        assert_eq!(LevelParams::at(200).difficulty, 0.9);
    }

    #[test]
    fn curriculum_moves_up_down_and_stays_in_range() {
        let never = || -> u8 { unreachable!("only past the last level") };
        assert_eq!(curriculum_update(3, 4.5, 10.0, never), 4);
        assert_eq!(curriculum_update(3, 2.0, 10.0, never), 2);
        assert_eq!(curriculum_update(3, 3.0, 5.0, never), 3);
        assert_eq!(curriculum_update(0, 0.0, 10.0, never), 0);
        assert_eq!(curriculum_update(LEVELS - 2, 9.0, 1.0, never), LEVELS - 1);
        // Walking out of the last level: wherever `after_last` says, within range.
        assert_eq!(curriculum_update(LEVELS - 1, 9.0, 1.0, || 3), 3);
        assert_eq!(
            curriculum_update(LEVELS - 1, 9.0, 1.0, || LEVELS - 1),
            LEVELS - 1
        );
        assert_eq!(curriculum_update(LEVELS - 1, 9.0, 1.0, || 200), LEVELS - 1);
        // Not walking out of it: stays, or moves down.
        assert_eq!(curriculum_update(LEVELS - 1, 3.0, 5.0, never), LEVELS - 1);
        assert_eq!(curriculum_update(LEVELS - 1, 0.0, 5.0, never), LEVELS - 2);
    }

    #[test]
    fn stairs_rise_to_the_platform_and_fall_for_the_down_variant() {
        let up = generate(TerrainKind::Stairs, 9, 0);
        let down = generate(TerrainKind::Stairs, 9, 1);
        let p = LevelParams::at(9);
        let top = up.height(0.0, 0.0);
        assert!((top - 8.0 * p.step_height).abs() < 1e-4, "{top}");
        assert!((down.height(0.0, 0.0) + top).abs() < 1e-4);
        assert_eq!(up.height(3.95, 0.0), 0.0);
    }

    #[test]
    fn rough_is_deterministic_and_bounded() {
        let a = generate(TerrainKind::Rough, 0, 0);
        let b = generate(TerrainKind::Rough, 0, 0);
        let ga = a.grid.as_ref().unwrap();
        assert_eq!(ga.h, b.grid.as_ref().unwrap().h);
        let p = LevelParams::at(0);
        assert!(ga.h.iter().all(|h| h.abs() <= p.roughness + 0.003));
        assert!(ga.h.iter().any(|h| *h != 0.0));
    }

    #[test]
    fn every_kind_repeats_every_sub_tile() {
        for kind in [TerrainKind::Rough, TerrainKind::Stairs, TerrainKind::Slopes] {
            let t = generate(kind, 6, 1);
            for (x, y) in [(0.3, -1.7), (2.05, 3.3), (-3.9, 0.0)] {
                let h = t.height(x, y);
                for (dx, dy) in [(SUB_TILE, 0.0), (0.0, -SUB_TILE), (-SUB_TILE, SUB_TILE)] {
                    let h2 = t.height(x + dx, y + dy);
                    assert!((h - h2).abs() < 1e-4, "{kind} at ({x}, {y}): {h} vs {h2}");
                }
            }
        }
    }

    #[test]
    fn evaluation_tiles_are_disjoint_from_training_tiles() {
        let train = TerrainSet::new(TerrainKind::Rough, TerrainUse::Train);
        let eval = TerrainSet::new(TerrainKind::Rough, TerrainUse::Eval);
        for level in 0..LEVELS as usize {
            for e in &eval.tiles[level] {
                let eh = &e.grid.as_ref().unwrap().h;
                for t in &train.tiles[level] {
                    let th = &t.grid.as_ref().unwrap().h;
                    let same = eh.iter().zip(th).filter(|(a, b)| a == b).count();
                    // Quantised uniform noise agrees by chance on a few per cent of points.
                    assert!(
                        (same as f64) < 0.2 * eh.len() as f64,
                        "level {level}: {same} of {} heights shared",
                        eh.len()
                    );
                }
            }
        }
    }

    #[test]
    fn mixed_deals_legged_gyms_proportions() {
        let count = |k: TerrainKind, v: u32| MIXED.iter().filter(|m| **m == (k, v)).count();
        assert_eq!(
            count(TerrainKind::Slopes, 0) + count(TerrainKind::Slopes, 1),
            2
        );
        assert_eq!(count(TerrainKind::Rough, 0), 6);
        assert_eq!(count(TerrainKind::Stairs, 0), 7);
        assert_eq!(count(TerrainKind::Stairs, 1), 5);
        let set = TerrainSet::new(TerrainKind::Mixed, TerrainUse::Train);
        let row = &set.tiles[6];
        assert_eq!(row.len(), 20);
        let p = LevelParams::at(6);
        // Tile 3 is stairs up, 4 stairs down, 0 a slope up: the platform heights show it.
        assert!((row[3].height(0.0, 0.0) - 8.0 * p.step_height).abs() < 1e-4);
        assert!((row[4].height(0.0, 0.0) + 8.0 * p.step_height).abs() < 1e-4);
        assert!(row[0].height(0.0, 0.0) > 0.5);
        assert!(row.iter().all(|t| t.kind == TerrainKind::Mixed));
        let eval = TerrainSet::new(TerrainKind::Mixed, TerrainUse::Eval);
        let rough = |t: &Tile| t.grid.as_ref().unwrap().h.clone();
        assert_ne!(
            rough(&row[2]),
            rough(&eval.tiles[6][2]),
            "evaluation draws its own fields"
        );
        assert_eq!(MIXED_NAMES[1], "slope_down");
    }

    #[test]
    fn parse_and_display_round_trip() {
        for k in TerrainKind::ALL {
            assert_eq!(k.to_string().parse::<TerrainKind>().unwrap(), k);
        }
        assert!("lava"
            .parse::<TerrainKind>()
            .unwrap_err()
            .to_string()
            .contains("flat, rough"));
    }
}
