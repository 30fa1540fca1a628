//! A piezoelectric harvester (Erturk–Inman form) with its voltage recorded: the system of
//! equations x'' = k₁x + k₃x³ + c v + χ V + F cos Ωt, V' = −λ V − κ v, by RK4.
//!
//! ```
//! use lssi_testkit::harvester::Piezo;
//! let points = Piezo::monostable().simulate(500, 0.01);
//! assert_eq!(points.len(), 500);
//! assert!(points.iter().any(|p| p.e.abs() > 1e-3), "the beam makes a voltage");
//! ```

/// One sample: time, displacement, velocity, voltage.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiezoPoint {
    /// Time, s.
    pub t: f64,
    /// Displacement.
    pub x: f64,
    /// Velocity.
    pub v: f64,
    /// Voltage across the load.
    pub e: f64,
}

/// The harvester's coefficients (the names of its equations above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piezo {
    /// Linear stiffness term of x'' (negative: monostable).
    pub k1: f64,
    /// Cubic stiffness term of x''.
    pub k3: f64,
    /// Damping term of x''.
    pub c: f64,
    /// Coupling χ of x'' to V.
    pub chi: f64,
    /// Electrical rate λ (1 / RC).
    pub lambda: f64,
    /// Coupling κ of V' to v.
    pub kappa: f64,
    /// Forcing amplitude F.
    pub force: f64,
    /// Forcing frequency Ω, rad/s.
    pub omega: f64,
}

impl Piezo {
    /// A monostable harvester (lssi-core's system tests' one).
    pub fn monostable() -> Self {
        Self {
            k1: -1.0,
            k3: -0.5,
            c: -0.04,
            chi: 0.1,
            lambda: 1.0,
            kappa: 0.5,
            force: 0.4,
            omega: 0.8,
        }
    }

    /// A bistable one (positive linear stiffness term).
    pub fn bistable() -> Self {
        Self {
            k1: 0.5,
            force: 0.3,
            ..Self::monostable()
        }
    }

    fn derivative(&self, t: f64, s: [f64; 3]) -> [f64; 3] {
        let [x, v, e] = s;
        [
            v,
            self.k1 * x
                + self.k3 * x * x * x
                + self.c * v
                + self.chi * e
                + self.force * (self.omega * t).cos(),
            -self.lambda * e - self.kappa * v,
        ]
    }

    /// `n` samples `dt` apart from x = 0.1 at rest, 10 RK4 steps a sample, after 100 s of
    /// transient are dropped.
    pub fn simulate(&self, n: usize, dt: f64) -> Vec<PiezoPoint> {
        let substeps = 10;
        let h = dt / substeps as f64;
        let mut s = [0.1, 0.0, 0.0];
        let skip = (100.0 / dt) as usize;
        let mut out = Vec::with_capacity(n);
        for i in 0..n + skip {
            let t0 = i as f64 * dt;
            if i >= skip {
                out.push(PiezoPoint {
                    t: t0,
                    x: s[0],
                    v: s[1],
                    e: s[2],
                });
            }
            for j in 0..substeps {
                let t = t0 + j as f64 * h;
                let add = |s: [f64; 3], k: [f64; 3], f: f64| {
                    [s[0] + f * k[0], s[1] + f * k[1], s[2] + f * k[2]]
                };
                let k1 = self.derivative(t, s);
                let k2 = self.derivative(t + h / 2.0, add(s, k1, h / 2.0));
                let k3 = self.derivative(t + h / 2.0, add(s, k2, h / 2.0));
                let k4 = self.derivative(t + h, add(s, k3, h));
                for k in 0..3 {
                    s[k] += h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
                }
            }
        }
        out
    }
}
