//! Fixed-step integration of a second-order ODE x'' = f(t, x, x'), for the data generators.
//!
//! The generators (`lssi gen paper`, later the harvester) need trajectories whose integration
//! error is far below anything the identifier can resolve: the benchmarks compare identified
//! coefficients at the 0.01 % level, so the data must satisfy the equation to about 1e-9.
//! Classical fourth-order Runge–Kutta with a small fixed step does that with no tuning and is
//! exactly reproducible, which an adaptive method with tolerances is not across step-size
//! heuristics.
//!
//! The integrator is `lssi_testkit::ode`, so that the core crate's tests make their data with
//! the very same steps without depending on the host tools.
//!
//! ```
//! use lssi_host::synth::ode::{State, integrate_at};
//!
//! // x'' = -x from x = 1, v = 0 is cos(t).
//! let times = [0.0, 0.5, 1.0];
//! let states = integrate_at(|_t, x, _v| -x, State { x: 1.0, v: 0.0 }, &times, 1e-3);
//! assert!((states[2].x - 1f64.cos()).abs() < 1e-12);
//! assert!((states[2].v + 1f64.sin()).abs() < 1e-12);
//! ```

pub use lssi_testkit::ode::{State, integrate_at, rk4_step, steps_for};
