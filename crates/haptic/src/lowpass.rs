//! First-order low-pass filter of the force sent to the device:
//! `y += a (x - y)`, `a = T / (T + 1 / (2 pi f_c))` (backward Euler of
//! `tau dy/dt = x - y` with `tau = 1 / (2 pi f_c)`). It smooths the step-to-step
//! changes of the force at the cost of a lag of about `tau`.

/// A first-order low-pass on 3-vectors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowPass {
    a: f64,
    y: Option<[f64; 3]>,
}

impl LowPass {
    /// A filter of cutoff `cutoff` Hz sampled every `period` s.
    pub fn new(cutoff: f64, period: f64) -> LowPass {
        let tau = 1.0 / (2.0 * std::f64::consts::PI * cutoff);
        LowPass {
            a: period / (period + tau),
            y: None,
        }
    }

    /// Filters one sample (the first passes through).
    pub fn apply(&mut self, x: [f64; 3]) -> [f64; 3] {
        let y = match self.y {
            None => x,
            Some(y) => std::array::from_fn(|i| y[i] + self.a * (x[i] - y[i])),
        };
        self.y = Some(y);
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step input reaches 1 - 1/e after about tau (exactly: (1 - a)^n = e^-1).
    #[test]
    fn a_step_rises_with_the_time_constant() {
        let (fc, t) = (10.0, 1e-3);
        let mut f = LowPass::new(fc, t);
        f.apply([0.0; 3]);
        let tau = 1.0 / (2.0 * std::f64::consts::PI * fc);
        let n = (tau / t).round() as usize; // 16 samples
        let mut y = [0.0; 3];
        for _ in 0..n {
            y = f.apply([1.0, 2.0, -1.0]);
        }
        // (1 - a)^16 with a = 1e-3 / (1e-3 + 15.9e-3) = 0.0591: 0.377, close to e^-1
        // = 0.368 (the backward Euler rounds tau up by half a sample).
        assert!((y[0] - 0.623).abs() < 0.005, "{y:?}");
        assert!((y[1] - 2.0 * y[0]).abs() < 1e-12 && (y[2] + y[0]).abs() < 1e-12);
    }
}
