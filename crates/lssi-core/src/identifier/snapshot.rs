//! Screening without a stall: what a screening reads, copied out of the identifier so that
//! the screening can run elsewhere (at a lower priority on a device) while samples go on.

use super::*;

/// What a screening reads, without the front end (ring buffers and derivative taps): an
/// [`Identifier`] of window capacity 1 and one channel, filled by
/// [`Identifier::snapshot_into`] and screened by [`Identifier::select`].
///
/// It keeps its own model between screenings (a screening that selects nothing leaves the
/// previous model, as in the identifier). About half the identifier's size (4.4 KiB with
/// f32 and P = 16, against 10 KiB for W = 256, C = 2).
///
/// ```
/// use lssi_core::{Config, Identifier, Sample, Snapshot};
/// let config = Config { sample_period: 0.01, window: 31, omega: 1.0,
///                       screening_period: 1500, ..Config::default() };
/// let mut inline: Identifier<f32, 64, 16> = Identifier::new(config).unwrap();
/// let mut deferred: Identifier<f32, 64, 16> = Identifier::new(config).unwrap();
/// let mut snapshot: Box<Snapshot<f32, 16>> = Box::new(Snapshot::empty());
/// for i in 0..3000u32 {
///     let t = f64::from(i) * 0.01;
///     let sample = Sample { t, x: (1.3 * t).sin() as f32 + 0.2 * (0.7 * t).cos() as f32,
///                           v: None, u: None };
///     inline.push(sample).unwrap();
///     deferred.push_with(sample, |id| { id.snapshot_into(&mut snapshot); false }).unwrap();
/// }
/// // The screening of the copy (later, elsewhere) gives the model of the inline one.
/// snapshot.select();
/// assert_eq!(snapshot.model().unwrap().coefficients, inline.model().unwrap().coefficients);
/// assert!(deferred.model().is_none());
/// ```
pub type Snapshot<T, const P: usize> = Identifier<T, 1, P, 1>;

impl<T: Real, const P: usize> Identifier<T, 1, P, 1> {
    /// An empty snapshot: `const`, all zero bytes (a static of it lies in `.bss`).
    pub const fn empty() -> Self {
        Self::zeroed()
    }

    /// Forgets the model (after the identifier it is taken from was configured anew).
    pub fn clear_model(&mut self) {
        self.model = None;
    }
}

impl<T: Real, const W: usize, const P: usize, const C: usize> Identifier<T, W, P, C> {
    /// Copies into `s` everything a screening reads (all but the front end's ring buffers
    /// and derivative taps, and `s`'s own model, which it keeps). Then `s.select()` is the
    /// screening of this identifier as it is now.
    ///
    /// Destructured field by field, so that a field added to the identifier does not
    /// compile until it is either copied here or said to be left out.
    pub fn snapshot_into<const W2: usize, const C2: usize>(
        &self,
        s: &mut Identifier<T, W2, P, C2>,
    ) {
        let Identifier {
            config,
            library,
            intake,
            schedule,
            front: _,
            noise,
            smoothing,
            offset,
            gate,
            extent,
            phasor,
            columns,
            scratch: _,
            halves,
            counters,
            model: _,
        } = self;
        s.config = *config;
        s.library.clone_from(library);
        s.intake = *intake;
        s.schedule = *schedule;
        s.noise = *noise;
        s.smoothing.clone_from(smoothing);
        s.offset = *offset;
        s.gate = *gate;
        s.extent = *extent;
        s.phasor = *phasor;
        s.columns = *columns;
        s.halves.clone_from(halves);
        s.counters = *counters;
    }
}
