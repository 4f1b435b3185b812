//! The gait score (paper Eq. 4, our reading in DESIGN.md) of a cell and the locomotion
//! metrics recorded beside it. The simulator computes it (`gaitsweep_sim::score`).

use serde::{Deserialize, Serialize};
/// The gait score of a cell and its components, averaged over its robots.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GaitScore {
    /// J = mean(track - effort - tilt) + progress, averaged over robots.
    pub score: f64,
    /// Mean velocity tracking kernel, in [0, 1].
    pub track: f64,
    /// Mean normalised torque |tau|_2 / (sqrt(12) tau_max), in [0, 1].
    pub effort: f64,
    /// Mean |g_xy| (horizontal part of gravity in the base frame).
    pub tilt: f64,
    /// Sum of squared per-step base displacements (m²).
    pub progress: f64,
    /// Fraction of robots that fell.
    pub fall_rate: f64,
    /// Mean |v_cmd - v| (m/s).
    pub mean_vel_error: f64,
    /// Mean absolute joint torque (N·m).
    pub mean_abs_torque: f64,
    /// Cost of transport: mean mechanical power / (m g mean speed).
    pub cost_of_transport: f64,
    /// Robots scored.
    pub robots: usize,
}
