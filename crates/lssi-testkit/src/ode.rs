//! Fixed-step integration of a second-order ODE x'' = f(t, x, x'), for the data generators.
//!
//! The host's generators (`lssi gen`, `lssi_host::synth::ode`) use this integrator too:
//! classical fourth-order Runge–Kutta with a small fixed step, exactly reproducible.
//!
//! ```
//! use lssi_testkit::ode::{State, integrate_at};
//!
//! // x'' = -x from x = 1, v = 0 is cos(t).
//! let times = [0.0, 0.5, 1.0];
//! let states = integrate_at(|_t, x, _v| -x, State { x: 1.0, v: 0.0 }, &times, 1e-3);
//! assert!((states[2].x - 1f64.cos()).abs() < 1e-12);
//! assert!((states[2].v + 1f64.sin()).abs() < 1e-12);
//! ```

/// The state of a single-degree-of-freedom oscillator: displacement and velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// Displacement x.
    pub x: f64,
    /// Velocity x'.
    pub v: f64,
}

/// Advances `state` from `t` to `t + h` with one classical fourth-order Runge–Kutta step.
///
/// `acceleration(t, x, v)` is the right-hand side f of x'' = f(t, x, x').
pub fn rk4_step<F>(acceleration: &F, t: f64, state: State, h: f64) -> State
where
    F: Fn(f64, f64, f64) -> f64,
{
    let State { x, v } = state;
    let half = 0.5 * h;

    // The first-order system is (x, v)' = (v, f(t, x, v)).
    let k1x = v;
    let k1v = acceleration(t, x, v);
    let k2x = v + half * k1v;
    let k2v = acceleration(t + half, x + half * k1x, v + half * k1v);
    let k3x = v + half * k2v;
    let k3v = acceleration(t + half, x + half * k2x, v + half * k2v);
    let k4x = v + h * k3v;
    let k4v = acceleration(t + h, x + h * k3x, v + h * k3v);

    State {
        x: x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v: v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    }
}

/// Number of equal RK4 steps that cover `span` with steps no longer than `max_step`.
///
/// Always at least one, so a zero or non-finite span still yields a (degenerate) step.
pub fn steps_for(span: f64, max_step: f64) -> u64 {
    let steps = (span / max_step).ceil();
    if steps.is_finite() && steps >= 1.0 {
        // `as` saturates for huge values; the caller bounds the span anyway.
        steps as u64
    } else {
        1
    }
}

/// Integrates x'' = `acceleration(t, x, x')` from `initial` at `times[0]` and returns the state
/// at every entry of `times`.
///
/// Between consecutive times the interval is split into equal RK4 steps no longer than
/// `max_step`, so any time grid works (uniform, jittered, or with gaps) and every sample lands
/// exactly on its time rather than on the nearest step. The result has the same length as
/// `times`; an empty `times` gives an empty result.
pub fn integrate_at<F>(acceleration: F, initial: State, times: &[f64], max_step: f64) -> Vec<State>
where
    F: Fn(f64, f64, f64) -> f64,
{
    let mut states = Vec::with_capacity(times.len());
    let Some((&first, rest)) = times.split_first() else {
        return states;
    };
    let mut state = initial;
    let mut t_prev = first;
    states.push(state);
    for &t_next in rest {
        let span = t_next - t_prev;
        let steps = steps_for(span, max_step);
        let h = span / steps as f64;
        for i in 0..steps {
            // Recomputing t from the interval start keeps round-off from accumulating.
            let t = t_prev + i as f64 * h;
            state = rk4_step(&acceleration, t, state, h);
        }
        states.push(state);
        t_prev = t_next;
    }
    states
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_cover_the_span() {
        assert_eq!(steps_for(1.0, 0.1), 10);
        assert_eq!(steps_for(1.0, 0.3), 4);
        assert_eq!(steps_for(0.0, 0.1), 1);
        assert_eq!(steps_for(f64::NAN, 0.1), 1);
    }

    #[test]
    fn empty_and_single_time() {
        let f = |_t: f64, x: f64, _v: f64| -x;
        let initial = State { x: 1.0, v: 0.0 };
        assert!(integrate_at(f, initial, &[], 0.1).is_empty());
        assert_eq!(integrate_at(f, initial, &[3.0], 0.1), vec![initial]);
    }

    #[test]
    fn rk4_is_exact_for_constant_acceleration() {
        // x'' = 2 is a quadratic in t, which RK4 integrates without truncation error.
        let s = rk4_step(&|_t, _x, _v| 2.0, 0.0, State { x: 1.0, v: 3.0 }, 0.5);
        assert!((s.x - (1.0 + 1.5 + 0.25)).abs() < 1e-15);
        assert!((s.v - 4.0).abs() < 1e-15);
    }
}
