//! Renders a robot's gait as an animated GIF: a perspective view of its terrain (as a
//! shaded wire mesh), body box, legs and feet, following the robot.

use std::path::Path;

use rapier3d::math::{Rotation, Vector};

use crate::error::{Error, Result};
use crate::terrain::Tile;

/// One frame of a robot's motion.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Base position.
    pub base_pos: Vector,
    /// Base orientation.
    pub base_rot: Rotation,
    /// Joint (link frame) positions, 3 per leg, in leg order.
    pub joints: Vec<Vector>,
    /// Foot centres, one per leg.
    pub feet: Vec<Vector>,
}

const W: usize = 480;
const H: usize = 320;
// Palette: 0 sky, 1..=8 terrain shades (low to high), 9 body, 10 legs, 11 feet, 12 text/dark.
const PALETTE: [u8; 39] = [
    235, 242, 250, // sky
    60, 90, 60, 75, 105, 70, 90, 120, 80, 105, 135, 90, 120, 150, 100, 140, 165, 115, 160, 180,
    130, 185, 200, 150, 200, 60, 40, // body
    40, 60, 160, // legs
    20, 20, 20, // feet
    30, 30, 30,
];

struct Canvas {
    px: Vec<u8>,
    depth: Vec<f32>,
}

struct Camera {
    eye: Vector,
    fwd: Vector,
    right: Vector,
    up: Vector,
    focal: f32,
}

impl Camera {
    fn looking_at(target: Vector, distance: f32) -> Camera {
        let eye = target + Vector::new(-0.55, -0.85, 0.45).normalize() * distance;
        let fwd = (target - eye).normalize();
        let right = fwd.cross(Vector::Z).normalize();
        let up = right.cross(fwd);
        Camera {
            eye,
            fwd,
            right,
            up,
            focal: W as f32 * 0.9,
        }
    }

    fn project(&self, p: Vector) -> Option<(f32, f32, f32)> {
        let d = p - self.eye;
        let z = d.dot(self.fwd);
        if z < 0.05 {
            return None;
        }
        Some((
            W as f32 / 2.0 + self.focal * d.dot(self.right) / z,
            H as f32 / 2.0 - self.focal * d.dot(self.up) / z,
            z,
        ))
    }
}

impl Canvas {
    fn new() -> Canvas {
        Canvas {
            px: vec![0; W * H],
            depth: vec![f32::INFINITY; W * H],
        }
    }

    fn dot(&mut self, x: i32, y: i32, z: f32, c: u8, r: i32) {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy > r * r {
                    continue;
                }
                let (xx, yy) = (x + dx, y + dy);
                if xx >= 0 && yy >= 0 && (xx as usize) < W && (yy as usize) < H {
                    let i = yy as usize * W + xx as usize;
                    if z <= self.depth[i] {
                        self.depth[i] = z;
                        self.px[i] = c;
                    }
                }
            }
        }
    }

    fn line(&mut self, cam: &Camera, a: Vector, b: Vector, c: u8, r: i32) {
        let (Some(pa), Some(pb)) = (cam.project(a), cam.project(b)) else {
            return;
        };
        let n = ((pb.0 - pa.0).abs().max((pb.1 - pa.1).abs()).ceil() as usize).clamp(1, 2000);
        for k in 0..=n {
            let t = k as f32 / n as f32;
            let (x, y, z) = (
                pa.0 + (pb.0 - pa.0) * t,
                pa.1 + (pb.1 - pa.1) * t,
                pa.2 + (pb.2 - pa.2) * t,
            );
            self.dot(x.round() as i32, y.round() as i32, z, c, r);
        }
    }
}

/// Draws the frames over `tile` and writes an animated GIF at `fps` frames per second.
pub fn write_gif(
    path: &Path,
    tile: &Tile,
    frames: &[Frame],
    half_extents: Vector,
    fps: u16,
) -> Result<()> {
    if frames.is_empty() {
        return Err(Error::InvalidArgument("no frames to render".into()));
    }
    let io =
        |e: std::io::Error| Error::InvalidArgument(format!("cannot write {}: {e}", path.display()));
    let file = std::fs::File::create(path).map_err(io)?;
    let mut enc = gif::Encoder::new(std::io::BufWriter::new(file), W as u16, H as u16, &PALETTE)
        .map_err(|e| Error::InvalidArgument(format!("gif {}: {e}", path.display())))?;
    enc.set_repeat(gif::Repeat::Infinite)
        .map_err(|e| Error::InvalidArgument(format!("gif: {e}")))?;
    let scale = half_extents.length().max(0.3);
    for f in frames {
        let mut cv = Canvas::new();
        let cam = Camera::looking_at(f.base_pos, 6.0 * scale);
        // Terrain: wire mesh around the robot, shaded by height.
        let (cx, cy) = (
            (f.base_pos.x / 0.2).round() * 0.2,
            (f.base_pos.y / 0.2).round() * 0.2,
        );
        let span = 8.0 * scale;
        let steps = (span / 0.2) as i32;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in -steps..=steps {
            for j in -steps..=steps {
                let h = tile.height(cx + i as f32 * 0.2, cy + j as f32 * 0.2);
                lo = lo.min(h);
                hi = hi.max(h);
            }
        }
        let shade = |h: f32| {
            1 + (((h - lo) / (hi - lo).max(1e-3)) * 7.0)
                .round()
                .clamp(0.0, 7.0) as u8
        };
        for i in -steps..=steps {
            for j in -steps..steps {
                let (x, y0, y1) = (
                    cx + i as f32 * 0.2,
                    cy + j as f32 * 0.2,
                    cy + (j + 1) as f32 * 0.2,
                );
                let (a, b) = (
                    Vector::new(x, y0, tile.height(x, y0)),
                    Vector::new(x, y1, tile.height(x, y1)),
                );
                cv.line(&cam, a, b, shade(a.z), 0);
                let (a2, b2) = (
                    Vector::new(y0 - cy + cx, x - cx + cy, 0.0),
                    Vector::new(y1 - cy + cx, x - cx + cy, 0.0),
                );
                let (a2, b2) = (
                    Vector::new(a2.x, a2.y, tile.height(a2.x, a2.y)),
                    Vector::new(b2.x, b2.y, tile.height(b2.x, b2.y)),
                );
                cv.line(&cam, a2, b2, shade(a2.z), 0);
            }
        }
        // Body box edges.
        let e = half_extents;
        let corner = |sx: f32, sy: f32, sz: f32| {
            f.base_pos + f.base_rot * Vector::new(sx * e.x, sy * e.y, sz * e.z)
        };
        for (a, b) in [
            ((-1., -1., -1.), (1., -1., -1.)),
            ((-1., 1., -1.), (1., 1., -1.)),
            ((-1., -1., 1.), (1., -1., 1.)),
            ((-1., 1., 1.), (1., 1., 1.)),
            ((-1., -1., -1.), (-1., 1., -1.)),
            ((1., -1., -1.), (1., 1., -1.)),
            ((-1., -1., 1.), (-1., 1., 1.)),
            ((1., -1., 1.), (1., 1., 1.)),
            ((-1., -1., -1.), (-1., -1., 1.)),
            ((1., -1., -1.), (1., -1., 1.)),
            ((-1., 1., -1.), (-1., 1., 1.)),
            ((1., 1., -1.), (1., 1., 1.)),
        ] {
            cv.line(&cam, corner(a.0, a.1, a.2), corner(b.0, b.1, b.2), 9, 2);
        }
        // Legs: hip -> thigh -> knee -> foot.
        for (leg, foot) in f.joints.chunks(3).zip(&f.feet) {
            let mut prev = leg[0];
            for p in leg.iter().skip(1).chain(std::iter::once(foot)) {
                cv.line(&cam, prev, *p, 10, 2);
                prev = *p;
            }
            if let Some((x, y, z)) = cam.project(*foot) {
                cv.dot(x.round() as i32, y.round() as i32, z - 0.01, 11, 4);
            }
        }
        let mut frame = gif::Frame::from_indexed_pixels(W as u16, H as u16, cv.px, None);
        frame.delay = (100 / fps.max(1)).max(2);
        enc.write_frame(&frame)
            .map_err(|e| Error::InvalidArgument(format!("gif {}: {e}", path.display())))?;
    }
    Ok(())
}
