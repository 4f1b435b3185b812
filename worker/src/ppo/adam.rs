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
#[derive(Debug)]
pub struct Adam {
    /// The parameters, in the order of [`super::ActorCritic::named_parameters`].
    pub params: Vec<Tensor>,
    /// First moments, one per parameter.
    pub m: Vec<Tensor>,
    /// Second moments, one per parameter.
    pub v: Vec<Tensor>,
    /// Steps taken (bias correction).
    pub step: u64,
    /// Current learning rate (the adaptive schedule changes it).
    pub lr: f64,
}

impl Adam {
    /// Fresh state with zero moments.
    pub fn new(params: Vec<Tensor>, lr: f64) -> Self {
        let m = params.iter().map(Tensor::zeros_like).collect();
        let v = params.iter().map(Tensor::zeros_like).collect();
        Self {
            params,
            m,
            v,
            step: 0,
            lr,
        }
    }

    /// Clears every gradient.
    pub fn zero_grad(&mut self) {
        for p in &mut self.params {
            p.zero_grad();
        }
    }

    /// Total L2 norm of the gradients; scales them down to `max_norm` when above it (as
    /// `torch.nn.utils.clip_grad_norm_`). Returns the norm before clipping.
    pub fn clip_grad_norm(&mut self, max_norm: f64) -> f64 {
        tch::no_grad(|| {
            let grads: Vec<Tensor> = self.params.iter().map(Tensor::grad).collect();
            let sq: Vec<Tensor> = grads
                .iter()
                .filter(|g| g.defined())
                .map(|g| g.square().sum(Kind::Float))
                .collect();
            let total = Tensor::stack(&sq, 0)
                .sum(Kind::Float)
                .sqrt()
                .double_value(&[]);
            let coef = max_norm / (total + 1e-6);
            if coef < 1.0 {
                for g in grads.iter().filter(|g| g.defined()) {
                    let mut g = g.shallow_clone();
                    g *= coef;
                }
            }
            total
        })
    }

    /// One Adam step with the current learning rate.
    pub fn step(&mut self) {
        self.step += 1;
        let bc1 = 1.0 - BETA1.powi(self.step as i32);
        let bc2 = 1.0 - BETA2.powi(self.step as i32);
        tch::no_grad(|| {
            for ((p, m), v) in self.params.iter_mut().zip(&mut self.m).zip(&mut self.v) {
                let g = p.grad();
                if !g.defined() {
                    continue;
                }
                *m *= BETA1;
                *m += &g * (1.0 - BETA1);
                *v *= BETA2;
                let _ = v.addcmul_(&g, &(&g * (1.0 - BETA2)));
                let denom = v.sqrt() / bc2.sqrt() + EPS;
                *p -= &*m / denom * (self.lr / bc1);
            }
        });
    }
}
