//! The device's replies, each framed into the link buffer and written out of line.

use crate::{CostUnit, Device, Transport, wire};
use lssi_proto::{
    CONTROL_SEQ, DeviceMsg, MAX_BATCH, NakReason, PROTOCOL_VERSION, SnapshotCause, encode,
};

impl<const W: usize, const P: usize, const C: usize> Device<W, P, C> {
    /// The `HelloReply`: the protocol version and this device's capacities.
    pub(crate) fn hello_reply(&self) -> DeviceMsg {
        DeviceMsg::HelloReply {
            protocol_version: PROTOCOL_VERSION,
            // Both fit: CAPACITIES_FIT.
            max_terms: u8::try_from(P).unwrap_or(u8::MAX),
            window_capacity: u16::try_from(W).unwrap_or(u16::MAX),
            max_batch: u16::try_from(MAX_BATCH).unwrap_or(u16::MAX),
        }
    }

    /// Sends `Ack { seq }`. Out of line, like every send: a [`DeviceMsg`] is as large as its
    /// largest variant (a snapshot, 0.6 KiB), and none may sit in the main loop's frame,
    /// under the screening.
    #[inline(never)]
    pub(crate) fn ack<L: Transport>(&mut self, link: &mut L, seq: u32) -> Result<(), L::Error> {
        self.send(link, &DeviceMsg::Ack { seq })
    }

    /// Sends `Nak { seq, reason }` (out of line, see [`Device::ack`]).
    #[inline(never)]
    pub(crate) fn nak<L: Transport>(
        &mut self,
        link: &mut L,
        seq: u32,
        reason: NakReason,
    ) -> Result<(), L::Error> {
        self.send(link, &DeviceMsg::Nak { seq, reason })
    }

    /// Sends `HelloReply` (out of line, see [`Device::ack`]).
    #[inline(never)]
    pub(crate) fn send_hello<L: Transport>(&mut self, link: &mut L) -> Result<(), L::Error> {
        self.send(link, &self.hello_reply())
    }

    /// Sends [`Device::health`] (its own frame: not under a screening).
    #[inline(never)]
    pub(crate) fn send_health<L: Transport>(
        &mut self,
        link: &mut L,
        unit: CostUnit,
    ) -> Result<(), L::Error> {
        self.send(link, &self.health(unit))
    }

    /// Sends the identifier's current model, if it has one (its own frame: the snapshot is
    /// not under a screening).
    #[inline(never)]
    pub(crate) fn send_model<L: Transport>(
        &mut self,
        link: &mut L,
        cause: SnapshotCause,
    ) -> Result<(), L::Error> {
        let snapshot = self
            .identifier
            .get()
            .and_then(|id| id.model())
            .and_then(|model| wire::snapshot(model, cause).ok());
        match snapshot {
            Some(snapshot) => self.send(link, &DeviceMsg::Model(snapshot)),
            None => Ok(()),
        }
    }

    /// Sends part `offset..` of the current model's bytes (`Nak NotConfigured` without a
    /// model). The snapshot is encoded into the link buffer, the part copied out of it, and
    /// the reply framed into the buffer again.
    #[inline(never)]
    pub(crate) fn send_model_part<L: Transport>(
        &mut self,
        link: &mut L,
        offset: u16,
    ) -> Result<(), L::Error> {
        let snapshot = self
            .identifier
            .get()
            .and_then(|id| id.model())
            .and_then(|model| wire::snapshot(model, SnapshotCause::Query).ok());
        let part = snapshot.and_then(|s| lssi_proto::model_part(&s, offset, &mut self.buffer));
        match part {
            Some(part) => self.send(link, &DeviceMsg::ModelPart(part)),
            None => self.nak(link, CONTROL_SEQ, NakReason::NotConfigured),
        }
    }

    /// Frames `message` into the link buffer and writes it. Only between frames: the
    /// frame received last has been handled.
    pub(crate) fn send<L: Transport>(
        &mut self,
        link: &mut L,
        message: &DeviceMsg,
    ) -> Result<(), L::Error> {
        // Cannot fail: the buffer holds the longest device frame.
        let Ok(len) = encode(message, &mut self.buffer) else {
            return Ok(());
        };
        link.write(self.buffer.get(..len).unwrap_or(&[]))
    }
}
