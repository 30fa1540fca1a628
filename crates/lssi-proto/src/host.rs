//! Host → device messages.

use crate::{BatchRef, CompactBatch, CompactRef, SampleBatch, SampleEncoding};
#[cfg(feature = "system")]
use crate::{SystemBatch, WireSystemConfig};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

/// A message from the host to the device.
///
/// The variant order is the wire discriminant (0..=8); see the README before changing it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[allow(
    clippy::large_enum_variant,
    reason = "no allocator to box into: a message is one fixed-size value"
)]
pub enum HostMsg {
    /// Opens the session. The device answers [`DeviceMsg::HelloReply`](crate::DeviceMsg).
    ///
    /// Frozen: this stays variant 0 with the version first in every protocol version.
    Hello {
        /// The host's [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
        protocol_version: u16,
    },
    /// Sets up (or replaces) the identifier; the device acks or naks `BadConfig`.
    Configure(WireConfig),
    /// Samples to run through the identifier, applied exactly once in `seq` order.
    Samples(SampleBatch),
    /// Asks for the current [`ModelSnapshot`](crate::ModelSnapshot) and health counters.
    Query,
    /// Drops the identifier's state; the configuration stays.
    Reset,
    /// Samples in the compact encoding ([`SampleEncoding::I16`]), applied like
    /// [`HostMsg::Samples`] (the same sequence numbers). Since version 5.
    Compact(CompactBatch),
    /// Asks for part `offset..` of the current model's bytes: the device answers
    /// [`DeviceMsg::ModelPart`](crate::DeviceMsg::ModelPart) (`Nak NotConfigured` without a
    /// model). Since version 5.
    ModelPart {
        /// Offset in the snapshot's postcard bytes.
        offset: u16,
    },
    /// Sets up (or replaces) a system's identifier (x'' and one equation per electrical
    /// channel, `lssi_core::SystemIdentifier`); acked or naked as `Configure`. Since version 6.
    #[cfg(feature = "system")]
    ConfigureSystem(WireSystemConfig),
    /// Samples for a system's identifier, numbered and applied like [`HostMsg::Samples`].
    /// Since version 6.
    #[cfg(feature = "system")]
    SystemSamples(SystemBatch),
}

/// A [`HostMsg`] decoded in place by [`decode_host_frame`](crate::decode_host_frame): a
/// sample batch stays in the received frame's bytes ([`BatchRef`]) instead of being copied
/// into a [`SampleBatch`].
#[derive(Clone, Debug, PartialEq)]
#[allow(
    clippy::large_enum_variant,
    reason = "a system batch is copied out of the frame (12 samples, 0.6 KiB): no allocator to box into"
)]
pub enum HostCommand<'a> {
    /// [`HostMsg::Hello`].
    Hello {
        /// The host's [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION).
        protocol_version: u16,
    },
    /// [`HostMsg::Configure`].
    Configure(WireConfig),
    /// [`HostMsg::Samples`], read from the frame's bytes.
    Samples(BatchRef<'a>),
    /// [`HostMsg::Query`].
    Query,
    /// [`HostMsg::Reset`].
    Reset,
    /// [`HostMsg::Compact`], read from the frame's bytes.
    Compact(CompactRef<'a>),
    /// [`HostMsg::ModelPart`].
    ModelPart {
        /// Offset in the snapshot's postcard bytes.
        offset: u16,
    },
    /// [`HostMsg::ConfigureSystem`].
    #[cfg(feature = "system")]
    ConfigureSystem(WireSystemConfig),
    /// [`HostMsg::SystemSamples`] (copied out of the frame: at most 12 samples).
    #[cfg(feature = "system")]
    SystemSamples(SystemBatch),
}

impl HostCommand<'_> {
    /// The same message as a [`HostMsg`] (copies a batch's samples out).
    pub fn to_msg(&self) -> HostMsg {
        match *self {
            #[cfg(feature = "system")]
            HostCommand::SystemSamples(ref batch) => HostMsg::SystemSamples(batch.clone()),
            HostCommand::Hello { protocol_version } => HostMsg::Hello { protocol_version },
            HostCommand::Configure(config) => HostMsg::Configure(config),
            HostCommand::Samples(batch) => HostMsg::Samples(batch.to_batch()),
            HostCommand::Query => HostMsg::Query,
            HostCommand::Reset => HostMsg::Reset,
            HostCommand::Compact(batch) => HostMsg::Compact(batch.to_batch()),
            HostCommand::ModelPart { offset } => HostMsg::ModelPart { offset },
            #[cfg(feature = "system")]
            HostCommand::ConfigureSystem(config) => HostMsg::ConfigureSystem(config),
        }
    }
}

/// Which monomials of (x, v) enter the library (the names of `lssi_core::PolyFamily`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PolyFamily {
    /// Every monomial x^a v^b with 1 ≤ a + b ≤ `poly_order`.
    All,
    /// The families x^k and x^(k-1)·v, k = 1..=`poly_order`.
    Families,
    /// The families x^k and x^(k-1)·v for odd k only (the paper's Table 7).
    OddFamilies,
}

/// The identifier's configuration as the host sends it: `lssi_core::Config`, field for field
/// and name for name (`library` and `channels` are its `LibraryConfig` and `Channels`).
///
/// The device rebuilds exactly the `Config` the host computed (`lssi_device::wire` holds
/// the conversions both sides use), so that the device's identifier and the host's
/// `lssi identify --f32` compute bit for bit the same model. Every float travels with the
/// width it has in `Config`. A plain record: the device validates it once, when it builds
/// the identifier, and naks [`NakReason::BadConfig`](crate::NakReason::BadConfig) if it
/// cannot. Field changes bump [`PROTOCOL_VERSION`](crate::PROTOCOL_VERSION); the nested
/// structs are no framing (postcard writes a struct as its fields in order), so the bytes
/// are those of the flat record of version 5 followed by `duty` (version 6; its
/// `model_every` since version 8).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireConfig {
    /// Nominal sample period in seconds (samples carry their own exact times).
    pub sample_period: f64,
    /// Window of the local derivative estimate, in samples.
    pub window: u16,
    /// Degree of the local polynomial of the derivative estimate.
    pub derivative_degree: u8,
    /// The candidate terms.
    pub library: WireLibrary,
    /// Base angular frequency Ω in rad/s, as the host chose or estimated it (ignored
    /// without harmonics; the device does not estimate it).
    pub omega: f64,
    /// Measured channels besides x.
    pub channels: WireChannels,
    /// Memory time constant of the forgetting factor in seconds; `None` forgets nothing.
    pub memory: Option<f64>,
    /// Samples between thresholding sweeps (M).
    pub screening_period: u32,
    /// Points of the logarithmic threshold grid.
    pub thresholds: u8,
    /// Whether k-neighbour smoothing is on.
    pub smoothing: bool,
    /// Use every `row_stride`-th sample as a regression row.
    pub row_stride: u16,
    /// MES parsimony: the sparsest solution within this fraction of the least held-out
    /// error is chosen.
    pub parsimony: f64,
    /// Whether the sensor offsets of x and v are estimated and removed.
    pub offsets: bool,
    /// A sample whose |x|, |v| or |u| exceeds this is rejected.
    pub max_abs: f64,
    /// Rows per test function (the weak form; 0: every row as it is). Since version 3.
    pub test_rows: u16,
    /// How the sample batches travel. Since version 5.
    pub encoding: SampleEncoding,
    /// A standalone device's duty cycle: identify for a window, report, sleep for an
    /// interval, wake and go on from the kept model; `None`: identify continuously. A
    /// device that samples no sensor of its own (the host sends the samples) ignores it.
    /// Since version 6.
    pub duty: Option<WireDuty>,
}

/// A standalone device's duty cycle (see [`WireConfig::duty`]). Since version 6.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireDuty {
    /// Seconds of sampling and identification a window (rounded by the device to whole
    /// rows).
    pub window: f32,
    /// Seconds asleep between two windows (rounded to whole rows).
    pub interval: f32,
    /// A model every this many windows (0 or 1: every window). The windows between end
    /// with Health only: their rows go into the identifier as every window's do, but no
    /// screening is run (a screening costs about as much energy as a window's rows), so
    /// the model made every `model_every`-th window, and the drift from the previous one,
    /// are those of a model every window. Since version 8.
    pub model_every: u16,
}

/// The candidate terms: `lssi_core::LibraryConfig`, field for field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireLibrary {
    /// Highest total order of the (x, v) monomials.
    pub poly_order: u8,
    /// Which monomials.
    pub family: PolyFamily,
    /// Whether the constant term is a candidate.
    pub constant: bool,
    /// sin/cos(kΩt) for k = 1..=`harmonics` (0 leaves them out).
    pub harmonics: u8,
    /// Whether the measured excitation u is a candidate term.
    pub input: bool,
}

/// Which measured channels the samples carry besides t and x: `lssi_core::Channels`, field
/// for field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, MaxSize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireChannels {
    /// A measured velocity v (otherwise it is estimated from x).
    pub velocity: bool,
    /// A measured excitation u.
    pub input: bool,
}
