//! Summaries of replicated results: mean, standard deviation and a 95% confidence
//! interval of the mean (Student's t, as the replicates are few).

use serde::{Deserialize, Serialize};

/// Mean and spread of a few replicated values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Number of values.
    pub n: usize,
    /// Their mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one value).
    pub sd: f64,
    /// Half-width of the 95% confidence interval of the mean, t(0.975, n-1) sd / sqrt(n)
    /// (0 for one value: no interval can be given).
    pub ci95: f64,
}

/// Two-sided 97.5% quantiles of Student's t for 1..=30 degrees of freedom.
const T975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// t(0.975, df): exact to 30 degrees of freedom, then the value at the tabulated df below
/// (30, 40, 60, 120), which errs wide: by at most 1% of the normal quantile past 120.
pub fn t975(df: usize) -> f64 {
    match df {
        0 => f64::INFINITY,
        d if d <= T975.len() => T975[d - 1],
        d if d < 40 => T975[T975.len() - 1],
        d if d < 60 => 2.021,
        d if d < 120 => 2.000,
        _ => 1.980,
    }
}

impl Summary {
    /// The summary of `values`; `None` when empty or any value is not finite.
    pub fn of(values: &[f64]) -> Option<Summary> {
        if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let n = values.len();
        let mean = values.iter().sum::<f64>() / n as f64;
        if n == 1 {
            return Some(Summary {
                n,
                mean,
                sd: 0.0,
                ci95: 0.0,
            });
        }
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd = var.sqrt();
        Some(Summary {
            n,
            mean,
            sd,
            ci95: t975(n - 1) * sd / (n as f64).sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_known_sample() {
        // 1, 2, 3: mean 2, sd 1, half-width 4.303 / sqrt(3).
        let s = Summary::of(&[1.0, 2.0, 3.0]).unwrap();
        assert_eq!((s.n, s.mean, s.sd), (3, 2.0, 1.0));
        assert!((s.ci95 - 4.303 / 3f64.sqrt()).abs() < 1e-12);
        assert_eq!(Summary::of(&[]), None);
        assert_eq!(Summary::of(&[1.0, f64::NAN]), None);
        assert_eq!(Summary::of(&[5.0]).unwrap().ci95, 0.0);
    }

    #[test]
    fn t_past_the_table_errs_wide_and_falls_towards_the_normal() {
        assert_eq!((t975(30), t975(31), t975(39)), (2.042, 2.042, 2.042));
        assert_eq!(
            (t975(40), t975(60), t975(120), t975(10_000)),
            (2.021, 2.000, 1.980, 1.980)
        );
        assert!(
            (1..200).all(|d| t975(d + 1) <= t975(d)),
            "never rises with df"
        );
    }
}
