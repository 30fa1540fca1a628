//! Systems of equations on the device (protocol version 6): a harvester's x'' and V' (or
//! i') from x and the electrical channel, by `lssi_core::SystemIdentifier` in f32.
//!
//! | host sends | device replies |
//! |---|---|
//! | `ConfigureSystem(c)` | builds the system's identifier from exactly `c` ([`system_config_from_wire`]); `Ack { CONTROL_SEQ }` (from then on `Query` and scheduled screenings send `SystemModel`, `Samples` and `Compact` are naked `NotConfigured`), or `Nak { CONTROL_SEQ, BadConfig }` (`TooManyTerms` for a library beyond P) and what was configured stays |
//! | `SystemSamples(b)` | as `Samples` (exactly once, in `seq` order; `Nak NotConfigured` unless a system is configured); a scheduled screening sends `SystemModel` (cause `Scheduled`) after the `Ack` |
//! | `Query`, `Reset` | as for one equation, with `SystemModel` instead of `Model` |
//! | `Configure(c)` | back to one equation |
//!
//! The conversions are the host's too: [`system_config_to_wire`] and
//! [`system_model_from_snapshot`] give the host the configuration it sends and the model
//! the device reports, so that the device's equations can be compared bit for bit with the
//! host's f32 `SystemIdentifier` on the same samples.

use crate::device::Mode;
use crate::wire::{WireError, config_from_wire, config_to_wire};
use crate::{CostMeter, Device, Stats, Transport};
use core::cmp::Ordering;
use lssi_core::identifier::system::{SystemConfigError, SystemModel, Target};
use lssi_core::library::{Electrical, StateTerm};
use lssi_core::{ConfigError, Real, SystemConfig};
use lssi_core::{SystemSample, SystemSlot};
use lssi_proto::DeviceMsg;
use lssi_proto::{
    CONTROL_SEQ, MAX_TERMS, NakReason, SnapshotCause, SolutionSummary, StateTermCode, SystemBatch,
    SystemEquation, SystemSnapshot, TermKind, WireElectrical, WireSystemConfig, WireTarget,
};

/// The wire form of a system's configuration; fails for a window beyond `u16::MAX` and for
/// two displacements (the wire and the device take one).
pub fn system_config_to_wire(config: &SystemConfig) -> Result<WireSystemConfig, WireError> {
    if config.displacements != 1 {
        return Err(WireError::Displacements(config.displacements));
    }
    Ok(WireSystemConfig {
        base: config_to_wire(&config.base)?,
        electrical: config.electrical.map(|e| e.map(electrical_to_wire)),
        coupling_order: config.coupling_order,
    })
}

/// The system configuration a [`WireSystemConfig`] describes, unvalidated.
pub fn system_config_from_wire(wire: &WireSystemConfig) -> SystemConfig {
    SystemConfig {
        base: config_from_wire(&wire.base),
        electrical: wire.electrical.map(|e| e.map(electrical_from_wire)),
        coupling_order: wire.coupling_order,
        displacements: 1,
    }
}

/// The nak of a `ConfigureSystem` that `error` refused.
pub fn system_config_nak(error: &SystemConfigError) -> NakReason {
    match error {
        SystemConfigError::Config(e) => crate::wire::config_nak(e),
        SystemConfigError::Library(lssi_core::library::StateLibraryError::Library(e)) => {
            crate::wire::config_nak(&ConfigError::Library(*e))
        }
        _ => NakReason::BadConfig,
    }
}

/// An electrical channel as the wire names it.
pub const fn electrical_to_wire(e: Electrical) -> WireElectrical {
    match e {
        Electrical::Voltage => WireElectrical::Voltage,
        Electrical::Current => WireElectrical::Current,
    }
}

/// The wire's electrical channel as lssi-core names it.
pub const fn electrical_from_wire(e: WireElectrical) -> Electrical {
    match e {
        WireElectrical::Voltage => Electrical::Voltage,
        WireElectrical::Current => Electrical::Current,
    }
}

/// A shared library term's wire code.
pub const fn state_term_code(term: StateTerm) -> StateTermCode {
    let (kind, powers) = match term {
        StateTerm::Constant => (TermKind::Constant, [0; 4]),
        // The wire's powers are those of x, v and the electrical channels: a device's system
        // has one displacement (x2 and v2 are 0).
        StateTerm::Monomial([px, pv, p2, p3, _, _]) => (TermKind::Monomial, [px, pv, p2, p3]),
        StateTerm::Sin(k) => (TermKind::Sin, [k, 0, 0, 0]),
        StateTerm::Cos(k) => (TermKind::Cos, [k, 0, 0, 0]),
        StateTerm::Input => (TermKind::Input, [0; 4]),
    };
    StateTermCode { kind, powers }
}

/// The term a wire code names; `None` for codes [`state_term_code`] never makes.
pub fn state_term_from_code(code: StateTermCode) -> Option<StateTerm> {
    match (code.kind, code.powers) {
        (TermKind::Constant, [0, 0, 0, 0]) => Some(StateTerm::Constant),
        (TermKind::Monomial, [px, pv, p2, p3]) if px + pv + p2 + p3 > 0 => {
            Some(StateTerm::Monomial([px, pv, p2, p3, 0, 0]))
        }
        (TermKind::Sin, [k, 0, 0, 0]) if k > 0 => Some(StateTerm::Sin(k)),
        (TermKind::Cos, [k, 0, 0, 0]) if k > 0 => Some(StateTerm::Cos(k)),
        (TermKind::Input, [0, 0, 0, 0]) => Some(StateTerm::Input),
        _ => None,
    }
}

/// An equation's target as the wire names it.
pub const fn target_to_wire(target: Target) -> WireTarget {
    match target {
        // x2'' never reaches the wire: a device's system has one displacement (its
        // configuration refuses two, see `system_config_to_wire`).
        Target::Acceleration | Target::Acceleration2 => WireTarget::Acceleration,
        Target::Rate(e) => WireTarget::Rate(electrical_to_wire(e)),
    }
}

/// The wire's target as lssi-core names it.
pub const fn target_from_wire(target: WireTarget) -> Target {
    match target {
        WireTarget::Acceleration => Target::Acceleration,
        WireTarget::Rate(e) => Target::Rate(electrical_from_wire(e)),
    }
}

/// The snapshot of a system's model: exact for `T = f32` (a device's), rounded for f64.
/// Fails when the library has more than [`MAX_TERMS`] terms (never on a device).
pub fn system_snapshot<T: Real, const P: usize, const E: usize>(
    model: &SystemModel<T, P, E>,
    cause: SnapshotCause,
) -> Result<SystemSnapshot, WireError> {
    let n = model.terms.len();
    let too_many = WireError::TooManyTerms {
        terms: n,
        capacity: MAX_TERMS,
    };
    let mut terms = heapless::Vec::new();
    for &term in model.terms.iter() {
        terms.push(state_term_code(term)).map_err(|_| too_many)?;
    }
    let mut equations = heapless::Vec::new();
    for equation in model.equations.iter() {
        let mut coefficients = heapless::Vec::new();
        for &c in equation.coefficients.iter().take(n) {
            coefficients.push(to_f32(c)).map_err(|_| too_many)?;
        }
        let selected = equation.selected_solution().map(|s| SolutionSummary {
            threshold: to_f32(s.threshold),
            mean_error: to_f32(s.mean_error),
            support: s.support,
        });
        let wire = SystemEquation {
            target: target_to_wire(equation.target),
            coefficients,
            selected,
            solutions: u8::try_from(equation.solutions.len()).unwrap_or(u8::MAX),
        };
        // At most E ≤ 1 + MAX_ELECTRICAL equations.
        if equations.push(wire).is_err() {
            break;
        }
    }
    Ok(SystemSnapshot {
        terms,
        equations,
        omega: model.omega,
        samples: model.samples,
        rejected: model.rejected,
        rows: model.rows,
        cause,
    })
}

/// The lssi-core model a system snapshot describes (the device's f32 values as they are),
/// so that the host reports it with lssi-core's own code (`SystemModel::write_equation`).
/// Each equation keeps only its selected solution (the snapshot carries no other).
pub fn system_model_from_snapshot<const P: usize>(
    snapshot: &SystemSnapshot,
) -> Result<SystemModel<f32, P, { lssi_proto::MAX_EQUATIONS }>, WireError> {
    let n = snapshot.terms.len();
    let too_many = WireError::TooManyTerms {
        terms: n,
        capacity: P,
    };
    let mut model = SystemModel {
        terms: heapless::Vec::new(),
        electrical: [None; lssi_core::library::MAX_ELECTRICAL],
        displacements: 1,
        equations: heapless::Vec::new(),
        omega: snapshot.omega,
        samples: snapshot.samples,
        rejected: snapshot.rejected,
        rows: snapshot.rows,
    };
    for &code in snapshot.terms.iter() {
        let term = state_term_from_code(code).ok_or(WireError::BadStateTerm(code))?;
        model.terms.push(term).map_err(|_| too_many)?;
    }
    let mut electrical = model.electrical.iter_mut();
    for equation in snapshot.equations.iter() {
        if equation.coefficients.len() != n {
            return Err(WireError::CoefficientCount {
                terms: n,
                coefficients: equation.coefficients.len(),
            });
        }
        let target = target_from_wire(equation.target);
        if let Target::Rate(e) = target
            && let Some(slot) = electrical.next()
        {
            *slot = Some(e);
        }
        let mut coefficients = [0.0f32; P];
        for (slot, &c) in coefficients.iter_mut().zip(equation.coefficients.iter()) {
            *slot = c;
        }
        let mut solutions = heapless::Vec::new();
        if let Some(s) = equation.selected {
            let _ = solutions.push(lssi_core::Solution {
                threshold: s.threshold,
                mean_error: s.mean_error,
                support: s.support,
            });
        }
        let _ = model
            .equations
            .push(lssi_core::identifier::system::Equation {
                target,
                coefficients,
                solutions,
                selected: 0,
            });
    }
    Ok(model)
}

fn to_f32<T: Real>(value: T) -> f32 {
    value.to_f64() as f32
}

impl<const W: usize, const P: usize, const C: usize> Device<W, P, C> {
    /// The system's configuration's base, once `ConfigureSystem` is in force.
    pub(crate) fn system_base_config(&self) -> Option<&lssi_core::Config> {
        self.system().map(|id| &id.config().base)
    }

    /// The system's accepted, rejected samples and screenings, once configured.
    pub(crate) fn system_counts(&self) -> Option<(u64, u64, u64)> {
        self.system().map(|id| {
            let c = id.counters();
            (c.accepted, c.rejected(), c.screenings)
        })
    }

    /// The system's identifier, once `ConfigureSystem` is in force.
    pub fn system(&self) -> Option<&lssi_core::SystemIdentifier<f32, W, P, 2, C>> {
        match self.mode {
            Mode::System => self.system.get(),
            Mode::Single => None,
        }
    }

    /// Out of line, like `configure`.
    #[inline(never)]
    pub(crate) fn configure_system<L: Transport>(
        &mut self,
        config: &WireSystemConfig,
        link: &mut L,
    ) -> Result<(), L::Error> {
        if config.base.encoding != lssi_proto::SampleEncoding::F32 {
            // System samples travel as `SystemSamples` only.
            return self.nak(link, CONTROL_SEQ, NakReason::BadConfig);
        }
        let config = system_config_from_wire(config);
        match self.system.configure(config) {
            Ok(_) => {
                log!(info, "system configured");
                self.mode = Mode::System;
                self.encoding = lssi_proto::SampleEncoding::F32;
                self.next_seq = 0;
                self.dirty = false;
                self.stats.reset_costs();
                self.ack(link, CONTROL_SEQ)
            }
            Err(error) => {
                let reason = system_config_nak(&error);
                self.nak(link, CONTROL_SEQ, reason)
            }
        }
    }

    /// Applies a system batch (exactly once, in `seq` order) and replies.
    pub(crate) fn system_batch<L: Transport, M: CostMeter>(
        &mut self,
        batch: &SystemBatch,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        let seq = batch.seq;
        if self.mode != Mode::System {
            return self.nak(link, seq, NakReason::NotConfigured);
        }
        let outcome = Self::apply_system(
            &mut self.system,
            &mut self.next_seq,
            &mut self.dirty,
            &mut self.stats,
            batch,
            meter,
        );
        match outcome {
            None => self.nak(link, seq, NakReason::NotConfigured),
            Some((Ordering::Less, _)) => self.ack(link, seq),
            Some((Ordering::Greater, _)) => self.nak(link, self.next_seq, NakReason::OutOfOrder),
            Some((Ordering::Equal, screened)) => {
                self.ack(link, seq)?;
                if screened {
                    self.send_system_model(link, SnapshotCause::Scheduled)?;
                }
                Ok(())
            }
        }
    }

    /// `None`: not configured; otherwise how `seq` compared with the next expected (the
    /// batch applied when equal) and whether a scheduled screening ran.
    fn apply_system<M: CostMeter>(
        slot: &mut SystemSlot<f32, W, P, 2, C>,
        next_seq: &mut u32,
        dirty: &mut bool,
        stats: &mut Stats,
        batch: &SystemBatch,
        meter: &mut M,
    ) -> Option<(Ordering, bool)> {
        let identifier = slot.get_mut()?;
        let order = batch.seq.cmp(next_seq);
        let mut screened = false;
        match order {
            Ordering::Less => stats.duplicates = stats.duplicates.wrapping_add(1),
            Ordering::Greater => {}
            Ordering::Equal => {
                for s in batch.samples.iter() {
                    let sample = SystemSample {
                        x2: None,
                        v2: None,
                        t: s.t,
                        x: s.x,
                        v: s.v,
                        u: s.u,
                        electrical: &s.electrical,
                    };
                    let (result, cost) = meter.measure(|| identifier.push(&sample));
                    *dirty = true;
                    if result == Ok(true) {
                        stats.record_screening(cost);
                        *dirty = false;
                        screened = true;
                    } else {
                        stats.record_sample(cost);
                    }
                }
                *next_seq = next_seq.saturating_add(1);
            }
        }
        Some((order, screened))
    }

    /// `Query` with a system configured: screens if samples came since the last
    /// screening, then `SystemModel` (if one exists) and `Health`.
    pub(crate) fn query_system<L: Transport, M: CostMeter>(
        &mut self,
        link: &mut L,
        meter: &mut M,
    ) -> Result<(), L::Error> {
        let Some(identifier) = self.system.get_mut() else {
            return self.nak(link, CONTROL_SEQ, NakReason::NotConfigured);
        };
        if self.dirty {
            let (ran, cost) = meter.measure(|| identifier.screen());
            if ran {
                self.stats.record_screening(cost);
            }
            self.dirty = false;
        }
        self.send_system_model(link, SnapshotCause::Query)?;
        self.send_health(link, meter.unit())
    }

    /// `Reset` with a system configured: rebuilt from the kept configuration.
    pub(crate) fn reset_system<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        let rebuilt = self.system.get_mut().map(|id| id.reconfigure(*id.config()));
        match rebuilt {
            Some(Ok(())) => {
                self.next_seq = 0;
                self.dirty = false;
                self.stats.reset_costs();
                self.ack(link, CONTROL_SEQ)
            }
            Some(Err(_)) | None => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
        }
    }

    /// Sends the system's model, if it has one (out of line: its own frame).
    #[inline(never)]
    pub(crate) fn send_system_model<L: Transport>(
        &mut self,
        link: &mut L,
        cause: SnapshotCause,
    ) -> Result<(), L::Error> {
        let snapshot = self
            .system
            .get()
            .and_then(|id| id.model())
            .and_then(|model| system_snapshot(model, cause).ok());
        match snapshot {
            Some(snapshot) => self.send(link, &DeviceMsg::SystemModel(snapshot)),
            None => Ok(()),
        }
    }
}
