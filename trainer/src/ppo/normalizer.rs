//! Running mean and variance of observations (rsl_rl's empirical normalisation), kept in
//! f64 on the host so that millions of samples do not lose precision; applied as f32
//! tensor ops, the same ops the TorchScript export records.

use tch::{Device, Kind, Tensor};

/// Added to the standard deviation before dividing (rsl_rl's value).
pub const NORM_EPS: f64 = 1e-2;
/// Normalised observations are clipped to +-this, so that a rare outlier (a robot
/// flipping over) cannot blow up the networks.
pub const NORM_CLIP: f64 = 10.0;

/// Running per-dimension mean and (population) variance.
#[derive(Clone, Debug, PartialEq)]
pub struct ObsNormalizer {
    /// Per-dimension mean.
    pub mean: Vec<f64>,
    /// Per-dimension variance.
    pub var: Vec<f64>,
    /// Number of observations folded in.
    pub count: u64,
}

impl ObsNormalizer {
    /// Zero mean, unit variance, nothing seen yet.
    pub fn new(dim: usize) -> Self {
        Self {
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            count: 0,
        }
    }

    /// Observation length.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Folds a batch `[n * dim]` in (Chan et al.'s parallel update).
    pub fn update(&mut self, batch: &[f32]) {
        let dim = self.dim();
        let n = batch.len() / dim;
        if n == 0 {
            return;
        }
        let mut bmean = vec![0.0f64; dim];
        for row in batch.chunks_exact(dim) {
            for (m, &x) in bmean.iter_mut().zip(row) {
                *m += x as f64;
            }
        }
        bmean.iter_mut().for_each(|m| *m /= n as f64);
        let mut bvar = vec![0.0f64; dim];
        for row in batch.chunks_exact(dim) {
            for ((v, &x), m) in bvar.iter_mut().zip(row).zip(&bmean) {
                let d = x as f64 - m;
                *v += d * d;
            }
        }
        bvar.iter_mut().for_each(|v| *v /= n as f64);
        let (na, nb) = (self.count as f64, n as f64);
        let tot = na + nb;
        for i in 0..dim {
            let delta = bmean[i] - self.mean[i];
            let m2 = self.var[i] * na + bvar[i] * nb + delta * delta * na * nb / tot;
            self.mean[i] += delta * nb / tot;
            self.var[i] = m2 / tot;
        }
        self.count += n as u64;
    }

    /// `(mean, std + eps)` as f32 tensors `[dim]` on `device`.
    pub fn tensors(&self, device: Device) -> (Tensor, Tensor) {
        let mean: Vec<f32> = self.mean.iter().map(|&m| m as f32).collect();
        let denom: Vec<f32> = self
            .var
            .iter()
            .map(|&v| (v.sqrt() + NORM_EPS) as f32)
            .collect();
        (
            Tensor::from_slice(&mean).to_device(device),
            Tensor::from_slice(&denom).to_device(device),
        )
    }

    /// Normalises raw observations `[B, dim]` with the tensors from [`Self::tensors`].
    pub fn apply(obs: &Tensor, mean: &Tensor, denom: &Tensor) -> Tensor {
        ((obs - mean) / denom).clamp(-NORM_CLIP, NORM_CLIP)
    }

    /// Mean and variance as f64 tensors `[dim]` (checkpoint form, exact).
    pub fn to_tensors_f64(&self) -> (Tensor, Tensor) {
        (
            Tensor::from_slice(&self.mean),
            Tensor::from_slice(&self.var),
        )
    }

    /// Rebuilds from the checkpoint form.
    pub fn from_tensors_f64(mean: &Tensor, var: &Tensor, count: u64) -> crate::Result<Self> {
        let mean = Vec::<f64>::try_from(mean.to_kind(Kind::Double).flatten(0, -1))?;
        let var = Vec::<f64>::try_from(var.to_kind(Kind::Double).flatten(0, -1))?;
        Ok(Self { mean, var, count })
    }
}
