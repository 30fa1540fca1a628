//! What the standalone instrument screens: one equation's [`Snapshot`] (x'' from x), or,
//! with the `system` feature, a system's [`SystemSnapshot`] (x'' and V' from x and V: two
//! ADC channels). Thread mode (the [`Reporter`](super::Reporter)) and the mailboxes
//! ([`Shared`](super::Shared)) are written once for both through [`Screening`].

use crate::wire;
use lssi_core::{Config, Snapshot};
use lssi_proto::{DeviceMsg, HostMsg, NakReason, SnapshotCause, WireConfig, WireDuty};

/// A host's configuration message as a flavour reads it: the configuration, its duty
/// cycle, and the `Configure` frame a board may keep in flash (one equation only).
pub type FromHost<C> = (C, Option<WireDuty>, Option<WireConfig>);

/// The snapshot a screening runs on, and what thread mode needs to know about its kind of
/// identifier.
pub trait Screening: 'static {
    /// What configures the identifier it is taken from ([`Config`] or `SystemConfig`).
    type Config: Copy;

    /// Forgets the model (the identifier was configured anew).
    fn clear_model(&mut self);

    /// The screening proper (bit for bit the one the identifier would have run in place).
    fn select(&mut self) -> bool;

    /// The latest model as the frame that reports it (`Model` or `SystemModel`).
    fn message(&self, cause: SnapshotCause) -> Option<DeviceMsg>;

    /// The single-equation part of a configuration (its rate, window, library).
    fn base(config: &Self::Config) -> &Config;

    /// Whether an identifier of window `W` and `C` channels takes `config` (`P` terms is
    /// the snapshot's own), and the nak that says why not.
    fn validate<const W: usize, const C: usize>(config: &Self::Config) -> Result<(), NakReason>;

    /// A host's configuration for this kind of identifier, if `message` is one.
    fn from_host(message: &HostMsg) -> Option<FromHost<Self::Config>>;
}

impl<const P: usize> Screening for Snapshot<f32, P> {
    type Config = Config;

    fn clear_model(&mut self) {
        Snapshot::clear_model(self);
    }

    fn select(&mut self) -> bool {
        Snapshot::select(self)
    }

    fn message(&self, cause: SnapshotCause) -> Option<DeviceMsg> {
        self.model()
            .and_then(|m| wire::snapshot(m, cause).ok())
            .map(DeviceMsg::Model)
    }

    fn base(config: &Config) -> &Config {
        config
    }

    fn validate<const W: usize, const C: usize>(config: &Config) -> Result<(), NakReason> {
        config
            .validate::<W, P, C>()
            .map_err(|e| wire::config_nak(&e))
    }

    fn from_host(message: &HostMsg) -> Option<FromHost<Config>> {
        match message {
            HostMsg::Configure(w) => Some((wire::config_from_wire(w), w.duty, Some(*w))),
            _ => None,
        }
    }
}

#[cfg(feature = "system")]
impl<const P: usize> Screening for lssi_core::SystemSnapshot<f32, P, 2> {
    type Config = lssi_core::SystemConfig;

    fn clear_model(&mut self) {
        lssi_core::SystemSnapshot::<f32, P, 2>::clear_model(self);
    }

    fn select(&mut self) -> bool {
        lssi_core::SystemSnapshot::<f32, P, 2>::select(self)
    }

    fn message(&self, cause: SnapshotCause) -> Option<DeviceMsg> {
        self.model()
            .and_then(|m| crate::system::system_snapshot(m, cause).ok())
            .map(DeviceMsg::SystemModel)
    }

    fn base(config: &lssi_core::SystemConfig) -> &Config {
        &config.base
    }

    fn validate<const W: usize, const C: usize>(
        config: &lssi_core::SystemConfig,
    ) -> Result<(), NakReason> {
        config
            .validate::<W, P, 2, C>()
            .map_err(|e| crate::system::system_config_nak(&e))
    }

    fn from_host(message: &HostMsg) -> Option<FromHost<lssi_core::SystemConfig>> {
        match message {
            HostMsg::ConfigureSystem(w) => {
                Some((crate::system::system_config_from_wire(w), w.base.duty, None))
            }
            _ => None,
        }
    }
}
