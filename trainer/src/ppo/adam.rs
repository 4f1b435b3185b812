//! Adam (as `torch.optim.Adam`) with its state in plain tensors, plus gradient-norm
//! clipping. tch's optimiser wrapper hides the moments, and the checkpoint must hold them
//! for a resumed run to continue bit-identically.

use tch::{Kind, Tensor};

/// Adam's exponential decay of the first moment.
pub const BETA1: f64 = 0.9;
/// Adam's exponential decay of the second moment.
pub const BETA2: f64 = 0.999;
/// Adam's denominator epsilon.
pub const EPS: f64 = 1e-8;

/// Adam state for an ordered list of parameters.
///
/// The moments live in two flat buffers and the step runs on one flat gradient, so that
/// an update is a dozen libtorch calls instead of a dozen per parameter tensor: with
/// legged_gym-sized networks the learner's time is mostly per-call overhead.
#[derive(Debug)]
pub struct Adam {
    /// The parameters, in the order of [`super::ActorCritic::named_parameters`].
    pub params: Vec<Tensor>,
    /// First moments, one per parameter (views into one flat buffer).
    pub m: Vec<Tensor>,
    /// Second moments, one per parameter (views into one flat buffer).
    pub v: Vec<Tensor>,
    /// Steps taken (bias correction).
    pub step: u64,
    /// Current learning rate (the adaptive schedule changes it).
    pub lr: f64,
    m_flat: Tensor,
    v_flat: Tensor,
    sizes: Vec<i64>,
    grad: Option<Tensor>,
}

impl Adam {
    /// Fresh state with zero moments.
    pub fn new(params: Vec<Tensor>, lr: f64) -> Self {
        let sizes: Vec<i64> = params.iter().map(|p| p.numel() as i64).collect();
        let total: i64 = sizes.iter().sum();
        let opts = match params.first() {
            Some(p) => (p.kind(), p.device()),
            None => (Kind::Float, tch::Device::Cpu),
        };
        let m_flat = Tensor::zeros([total], opts);
        let v_flat = Tensor::zeros([total], opts);
        let views = |flat: &Tensor| -> Vec<Tensor> {
            flat.split_with_sizes(&sizes, 0)
                .into_iter()
                .zip(&params)
                .map(|(t, p)| t.view(p.size().as_slice()))
                .collect()
        };
        let (m, v) = (views(&m_flat), views(&v_flat));
        Self {
            params,
            m,
            v,
            step: 0,
            lr,
            m_flat,
            v_flat,
            sizes,
            grad: None,
        }
    }

    /// Clears every gradient.
    pub fn zero_grad(&mut self) {
        for p in &mut self.params {
            p.zero_grad();
        }
        self.grad = None;
    }

    /// The gradients as one flat tensor (zeros where a parameter got none).
    fn flat_grad(&self) -> Tensor {
        let parts: Vec<Tensor> = self
            .params
            .iter()
            .map(|p| {
                let g = p.grad();
                if g.defined() {
                    g.reshape([-1])
                } else {
                    p.zeros_like().reshape([-1])
                }
            })
            .collect();
        Tensor::cat(&parts, 0)
    }

    /// Total L2 norm of the gradients; scales them down to `max_norm` when above it (as
    /// `torch.nn.utils.clip_grad_norm_`). Returns the norm before clipping. The clipped
    /// gradient is what the next [`Adam::step`] uses.
    pub fn clip_grad_norm(&mut self, max_norm: f64) -> f64 {
        tch::no_grad(|| {
            let mut g = self.flat_grad();
            let total = g.norm().double_value(&[]);
            let coef = max_norm / (total + 1e-6);
            if coef < 1.0 {
                g *= coef;
            }
            self.grad = Some(g);
            total
        })
    }

    /// One Adam step with the current learning rate.
    pub fn step(&mut self) {
        self.step += 1;
        let bc1 = 1.0 - BETA1.powi(self.step as i32);
        let bc2 = 1.0 - BETA2.powi(self.step as i32);
        tch::no_grad(|| {
            let g = match self.grad.take() {
                Some(g) => g,
                None => self.flat_grad(),
            };
            let _ = self.m_flat.lerp_(&g, 1.0 - BETA1);
            self.v_flat *= BETA2;
            let _ = self.v_flat.addcmul_(&g, &(&g * (1.0 - BETA2)));
            let denom = self.v_flat.sqrt() / bc2.sqrt() + EPS;
            let update = &self.m_flat / denom * (self.lr / bc1);
            for (p, u) in self
                .params
                .iter_mut()
                .zip(update.split_with_sizes(&self.sizes, 0))
            {
                *p -= u.view(p.size().as_slice());
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// torch.optim.Adam's update written out on the host, for `loss = sum(x^2)/2 + sum(c*y)`.
    #[test]
    fn step_matches_the_adam_formula_and_moments_are_views() {
        let x0 = [1.0f32, -2.0, 0.5];
        let y0 = [0.3f32, 0.1, -0.7, 2.0];
        let c = [0.5f32, -1.0, 2.0, 0.25];
        let x = Tensor::from_slice(&x0).set_requires_grad(true);
        let y = Tensor::from_slice(&y0).view([2, 2]).set_requires_grad(true);
        let ct = Tensor::from_slice(&c).view([2, 2]);
        let lr = 0.01;
        let mut opt = Adam::new(vec![x.shallow_clone(), y.shallow_clone()], lr);
        let mut p: Vec<f64> = x0.iter().chain(&y0).map(|&v| v as f64).collect();
        let (mut m, mut v) = (vec![0.0f64; 7], vec![0.0f64; 7]);
        for t in 1..=3 {
            opt.zero_grad();
            let loss = x.square().sum(Kind::Float) * 0.5 + (&y * &ct).sum(Kind::Float);
            loss.backward();
            let norm = opt.clip_grad_norm(1e9);
            opt.step();
            let g: Vec<f64> = (0..7)
                .map(|i| if i < 3 { p[i] } else { c[i - 3] as f64 })
                .collect();
            let want_norm = g.iter().map(|g| g * g).sum::<f64>().sqrt();
            assert!((norm - want_norm).abs() < 1e-5, "{norm} vs {want_norm}");
            for i in 0..7 {
                m[i] = BETA1 * m[i] + (1.0 - BETA1) * g[i];
                v[i] = BETA2 * v[i] + (1.0 - BETA2) * g[i] * g[i];
                let mh = m[i] / (1.0 - BETA1.powi(t));
                let vh = v[i] / (1.0 - BETA2.powi(t));
                p[i] -= lr * mh / (vh.sqrt() + EPS);
            }
        }
        let got: Vec<f64> = [&x, &y.view([-1])]
            .iter()
            .flat_map(|t| Vec::<f32>::try_from(t.detach()).unwrap())
            .map(|v| v as f64)
            .collect();
        for (a, b) in got.iter().zip(&p) {
            assert!((a - b).abs() < 1e-6, "{got:?} vs {p:?}");
        }
        // The per-parameter moments (what checkpoints hold) see the flat buffers' state.
        let m0 = Vec::<f32>::try_from(&opt.m[0]).unwrap();
        assert!((m0[0] as f64 - m[0]).abs() < 1e-6, "{m0:?} vs {m:?}");
        assert_eq!(opt.v[1].size(), vec![2, 2]);
    }

    #[test]
    fn clipping_scales_the_step_gradient() {
        let x = Tensor::from_slice(&[3.0f32, 4.0]).set_requires_grad(true);
        let mut opt = Adam::new(vec![x.shallow_clone()], 0.1);
        opt.zero_grad();
        (x.square().sum(Kind::Float) * 0.5).backward();
        let norm = opt.clip_grad_norm(1.0);
        assert!((norm - 5.0).abs() < 1e-5);
        opt.step();
        // m = (1 - beta1) * g_clipped; bias-corrected, the first step is lr * sign(g).
        let m0 = Vec::<f32>::try_from(&opt.m[0]).unwrap();
        assert!(
            (m0[0] - 0.1 * 0.6).abs() < 1e-6 && (m0[1] - 0.1 * 0.8).abs() < 1e-6,
            "{m0:?}"
        );
    }
}
