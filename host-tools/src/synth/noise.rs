//! Measurement noise as the paper adds it, eq. (16):
//!
//! G = g + δ C₀ e,  C₀ = ‖g‖₂ / ‖e‖₂,
//!
//! so the noise δ C₀ e always has 2-norm δ‖g‖₂ whatever the distribution of e. The paper draws
//! e uniformly in (0, 1) ([`NoiseKind::Paper`]); that noise is not zero-mean, and its mean,
//! δ‖g‖₂ E(e)/√(n E(e²)) = (√3/2) δ rms(g) ≈ 0.866 δ rms(g), biases every channel. The other
//! kinds keep the same norm with zero mean, so a benchmark can tell the bias apart from the
//! scatter.
//!
//! ```
//! use lssi_host::synth::noise::{NoiseKind, add_noise};
//! use rand::SeedableRng;
//!
//! let clean = vec![1.0; 1000];
//! let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(1);
//! let noisy = add_noise(&clean, 0.01, NoiseKind::Gauss, &mut rng);
//! let noise_norm = noisy.values.iter().zip(&clean).map(|(g, c)| (g - c).powi(2)).sum::<f64>().sqrt();
//! let clean_norm = 1000f64.sqrt();
//! assert!((noise_norm / clean_norm - 0.01).abs() < 1e-12);
//! ```

use rand::RngExt;
use rand::distr::Open01;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

/// The distribution of the raw noise e in eq. (16), before it is scaled to norm δ‖g‖₂.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum NoiseKind {
    /// e uniform in (0, 1), as in the paper: biased by ≈ 0.866 δ rms(g).
    Paper,
    /// e uniform in (-1, 1): zero-mean, same norm.
    Uniform0,
    /// e standard Gaussian: zero-mean, same norm.
    Gauss,
}

impl NoiseKind {
    /// The name used on the command line and in truth files.
    pub fn name(self) -> &'static str {
        match self {
            NoiseKind::Paper => "paper",
            NoiseKind::Uniform0 => "uniform0",
            NoiseKind::Gauss => "gauss",
        }
    }

    /// Draws one raw noise value e.
    fn draw<R: rand::Rng + ?Sized>(self, rng: &mut R) -> f64 {
        match self {
            NoiseKind::Paper => rng.sample(Open01),
            NoiseKind::Uniform0 => 2.0 * rng.sample::<f64, _>(Open01) - 1.0,
            NoiseKind::Gauss => rng.sample(StandardNormal),
        }
    }
}

/// Mean and root-mean-square of the noise that was added to one channel.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct NoiseStats {
    /// Mean of the added noise (the bias it puts on the channel).
    pub offset: f64,
    /// Root mean square of the added noise.
    pub rms: f64,
}

/// A channel with noise added, and what was added.
#[derive(Debug, Clone, PartialEq)]
pub struct Noisy {
    /// The noisy data G.
    pub values: Vec<f64>,
    /// Mean and rms of G − g.
    pub stats: NoiseStats,
}

/// Adds eq. (16) noise of level `delta` (δ) and kind `kind` to `clean` (g).
///
/// Draws exactly `clean.len()` values from `rng`, even when `delta` is zero, so the draws for a
/// later channel do not depend on this channel's δ. When ‖g‖₂ or ‖e‖₂ is zero the noise is zero.
pub fn add_noise<R: rand::Rng + ?Sized>(
    clean: &[f64],
    delta: f64,
    kind: NoiseKind,
    rng: &mut R,
) -> Noisy {
    let raw: Vec<f64> = clean.iter().map(|_| kind.draw(rng)).collect();
    let clean_norm = norm(clean);
    let raw_norm = norm(&raw);
    let scale = if raw_norm > 0.0 {
        delta * clean_norm / raw_norm
    } else {
        0.0
    };
    let noise: Vec<f64> = raw.iter().map(|e| scale * e).collect();
    let values = clean.iter().zip(&noise).map(|(g, n)| g + n).collect();
    Noisy {
        values,
        stats: stats(&noise),
    }
}

/// The Euclidean norm ‖values‖₂.
pub fn norm(values: &[f64]) -> f64 {
    values.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Mean and root-mean-square of `values`; zeros for an empty slice.
pub fn stats(values: &[f64]) -> NoiseStats {
    if values.is_empty() {
        return NoiseStats::default();
    }
    let n = values.len() as f64;
    NoiseStats {
        offset: values.iter().sum::<f64>() / n,
        rms: norm(values) / n.sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;

    #[test]
    fn zero_delta_adds_nothing_but_still_draws() {
        let mut a = ChaCha8Rng::seed_from_u64(3);
        let mut b = ChaCha8Rng::seed_from_u64(3);
        let clean = [1.0, -2.0, 3.0];
        let noisy = add_noise(&clean, 0.0, NoiseKind::Paper, &mut a);
        assert_eq!(noisy.values, clean);
        add_noise(&clean, 0.5, NoiseKind::Paper, &mut b);
        assert_eq!(a.random::<u64>(), b.random::<u64>());
    }

    #[test]
    fn empty_channel() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let noisy = add_noise(&[], 0.1, NoiseKind::Gauss, &mut rng);
        assert!(noisy.values.is_empty());
        assert_eq!(noisy.stats, NoiseStats::default());
    }
}
