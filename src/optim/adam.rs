//! Adam (Kingma & Ba 2015) over a flat f64 parameter vector.
use crate::{Error, Result};

#[derive(Clone, Debug, PartialEq)]
pub struct Adam {
    pub learning_rate: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub epsilon: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// The usual betas (0.9, 0.999) and epsilon 1e-8, for `len` parameters.
    pub fn new(len: usize, learning_rate: f64) -> Self {
        Self { learning_rate, beta1: 0.9, beta2: 0.999, epsilon: 1e-8, m: vec![0.0; len], v: vec![0.0; len], t: 0 }
    }

    /// One step: `params -= lr * m_hat / (sqrt(v_hat) + eps)`.
    pub fn step(&mut self, params: &mut [f64], grads: &[f64]) -> Result<()> {
        if params.len() != self.m.len() || grads.len() != self.m.len() {
            return Err(Error::data(format!("Adam holds {} parameters, got {} and {} gradients", self.m.len(), params.len(), grads.len())));
        }
        self.t += 1;
        let (c1, c2) = (1.0 - self.beta1.powi(self.t), 1.0 - self.beta2.powi(self.t));
        for ((p, &g), (m, v)) in params.iter_mut().zip(grads).zip(self.m.iter_mut().zip(self.v.iter_mut())) {
            *m = self.beta1 * *m + (1.0 - self.beta1) * g;
            *v = self.beta2 * *v + (1.0 - self.beta2) * g * g;
            *p -= self.learning_rate * (*m / c1) / ((*v / c2).sqrt() + self.epsilon);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_moves_each_parameter_by_the_learning_rate() {
        // Bias correction makes the first step exactly lr * sign(g) (up to epsilon).
        let mut adam = Adam::new(3, 0.1);
        let mut p = vec![1.0, 2.0, 3.0];
        adam.step(&mut p, &[5.0, -0.01, 1e3]).unwrap();
        for (after, expected) in p.iter().zip([0.9, 2.1, 2.9]) {
            assert!((after - expected).abs() < 1e-6, "{after} vs {expected}");
        }
    }

    #[test]
    fn minimises_an_ill_conditioned_quadratic() {
        // f = x^2 + 1000 y^2 from (3, -2): Adam's per-coordinate scaling copes with the
        // conditioning; 500 steps at lr 0.05 land within 0.05 of the minimum.
        let mut adam = Adam::new(2, 0.05);
        let mut p = vec![3.0, -2.0];
        for _ in 0..500 {
            let g = [2.0 * p[0], 2000.0 * p[1]];
            adam.step(&mut p, &g).unwrap();
        }
        assert!(p[0].abs() < 0.05 && p[1].abs() < 0.05, "{p:?}");
    }

    #[test]
    fn mismatched_lengths_are_an_error() {
        assert!(Adam::new(2, 0.1).step(&mut [0.0; 3], &[0.0; 3]).is_err());
    }
}
