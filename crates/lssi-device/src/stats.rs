//! The device's own counters.

#[cfg(doc)]
use crate::Device;
#[cfg(doc)]
use lssi_proto::DeviceMsg;

/// The device's own counters (what [`DeviceMsg::Health`] reports besides the identifier's).
///
/// Link counters count since power-up; cost figures since the identifier was last
/// (re)built by `Configure` or `Reset`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// [`Device::poll`] calls (the watchdog: stuck means the main loop hangs).
    pub watchdog: u32,
    /// Frames that decoded.
    pub frames_ok: u32,
    /// Frames dropped for COBS, CRC or overrunning the receive buffer.
    pub crc_errors: u32,
    /// Frames that passed the CRC but did not decode.
    pub decode_errors: u32,
    /// Sample batches received again after they had been applied.
    pub duplicates: u32,
    /// Samples pushed without a screening, whose cost is in `cost_sum`.
    pub cost_count: u64,
    /// Sum of their costs.
    pub cost_sum: u64,
    /// The largest of them.
    pub cost_max: u32,
    /// Cost of the latest screening (scheduled, within a push, or queried).
    pub screen_cost: u32,
    /// Largest cost of a screening.
    pub screen_cost_max: u32,
}

impl Stats {
    /// Mean per-sample cost (0 before any sample), saturating at `u32::MAX`.
    pub fn cost_mean(&self) -> u32 {
        match self.cost_sum.checked_div(self.cost_count) {
            Some(mean) => u32::try_from(mean).unwrap_or(u32::MAX),
            None => 0,
        }
    }

    pub(crate) fn record_sample(&mut self, cost: u32) {
        self.cost_count = self.cost_count.saturating_add(1);
        self.cost_sum = self.cost_sum.saturating_add(u64::from(cost));
        self.cost_max = self.cost_max.max(cost);
    }

    pub(crate) fn record_screening(&mut self, cost: u32) {
        self.screen_cost = cost;
        self.screen_cost_max = self.screen_cost_max.max(cost);
    }

    pub(crate) fn reset_costs(&mut self) {
        self.cost_count = 0;
        self.cost_sum = 0;
        self.cost_max = 0;
        self.screen_cost = 0;
        self.screen_cost_max = 0;
    }
}
