//! Decimation: the ADC samples fast (what its anti-alias filter needs) and the identifier
//! takes one row per `factor` conversions.
//!
//! A harvester rings at 3–50 Hz; the identifier needs 30–60 rows a forcing period, a few
//! hundred rows a second. A part whose ADC converts at kilohertz rates (a simple RC
//! anti-alias filter at a few hundred hertz leaves the band above it to the digital filter)
//! averages the conversions down to that row rate:
//!
//! - on the STM32F4 in software, by this [`Decimator`]: a CIC (cascaded integrator–comb)
//!   filter of order 1–3, written as its FIR form, sinc^N of length N·(D − 1) + 1, DC
//!   gain exactly 1. Each conversion costs N multiply-adds per channel; with the ADC's DMA
//!   filling a block of D conversions, the core wakes once per row instead;
//! - on the STM32L4 in hardware: the ADC's oversampler (`ADC_CFGR2.OVSR`, ratio 2–256, and
//!   `OVSS`, a right shift) accumulates D conversions and delivers their mean, a sinc¹ of
//!   length D — the [`Decimator`] of order 1 computes the same thing, and the core wakes
//!   once per row with no code per conversion.
//!
//! Droop compensation: sinc^N is not flat in the passband: its gain is about
//! `1 − N (π f / f_r)² / 6` (f_r the row rate), 1.1 % low at 10.2 Hz for order 3 at
//! 212.8 rows/s (eveh's third harmonic at the rate `lssi identify` proposes). A gain that
//! falls with frequency is, to the identifier, a harmonic-dependent distortion of x, and it
//! fits it with a spurious term (x·v² ≈ −13,500 on eveh, every seed). Every decimating
//! [`Decimator`] (factor above 1, every order, the L4's oversampler's rows too: its CIC of
//! order 1 in hardware, this stage in software) therefore follows the CIC by a 3-tap
//! symmetric compensator on the rows, `c_r = (1 + 2a)·y_r − a·(y_{r−1} + y_{r+1})` with
//! `a = N/24`, whose gain `1 + 2a(1 − cos(2π f / f_r)) ≈ 1 + N (π f / f_r)² / 6` cancels
//! the droop to second order (the residual is fourth order: 0.015 % at 10.2 Hz, order 3, D 47).
//! It costs 3 multiply-adds a row a channel (nothing per conversion) and one row of latency,
//! counted in the rows' times: output row `j` is the compensated `y_{j+1}` and stands for its
//! instant. Its DC gain is 1, its taps sum to 1, and it is computed in f32, in this order, on
//! the device and in the host's tests alike (bit for bit).
//!
//! The row's value is centred on its kernel: row `r` stands for the ADC instant
//! `r·D + `[`Decimator::centre`] (in conversions since the first one, the compensator's row
//! of latency included). The identifier's time for row `r` is `r·(D / f_adc) + centre /
//! f_adc` (see [`Decimator::time_offset`]): a filter delay left in the times would turn the
//! forcing's sin/cos coefficients (a phase), not the dynamics, but the truth has them at the
//! ADC's own time.
//!
//! Alias attenuation: a row rate f_r folds f_r ± f onto f. The response at frequency f is
//! `|sin(π f D / f_adc) / (D sin(π f / f_adc))|^N · (1 + 2a(1 − cos(2π f D / f_adc)))`
//! ([`Decimator::gain_at`]; the compensator gains as much on an alias f_r − f as on f,
//! +0.4 dB for order 3 at f = f_r / 10); at f_r − f_b (f_b the highest frequency that
//! matters, e.g. f_r / 10) order 3 gives about −57 dB, order 1 (the L4's oversampler)
//! about −19 dB, so that part wants its RC filter to do more.

/// Highest CIC order.
pub const MAX_ORDER: u8 = 3;
/// Largest decimation factor: the order-3 weights (up to D²) and their norm (D³) stay exact
/// in f32 (below 2²⁴).
pub const MAX_FACTOR: u32 = 255;

/// Why a decimation cannot be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DecimationError {
    /// The factor is 0 or above [`MAX_FACTOR`].
    Factor(u32),
    /// The order is 0 or above [`MAX_ORDER`].
    Order(u8),
}

impl core::fmt::Display for DecimationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DecimationError::Factor(d) => write!(
                f,
                "the decimation factor is {d}, but it must be 1 to {MAX_FACTOR} ADC conversions a row"
            ),
            DecimationError::Order(n) => {
                write!(f, "the CIC order is {n}, but it must be 1 to {MAX_ORDER}")
            }
        }
    }
}

impl core::error::Error for DecimationError {}

/// The decimation factor that turns `adc_hz` conversions a second into rows every
/// `row_period` seconds: the nearest integer, if it is within 0.1 % of the ratio (the row
/// period is then `factor / adc_hz`, which the identifier must be configured with).
pub fn factor_for(adc_hz: f64, row_period: f64) -> Option<u32> {
    let ratio = adc_hz * row_period;
    if !(ratio.is_finite() && ratio >= 0.5) {
        return None;
    }
    let d = libm::round(ratio);
    if libm::fabs(ratio - d) > 1e-3 * d || d > f64::from(MAX_FACTOR) {
        return None;
    }
    Some(d as u32)
}

/// A sinc^N decimator of up to three channels (x, and v and u when present): one output
/// row every `factor` inputs, the mean of the inputs weighted by the CIC kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decimator {
    factor: u32,
    order: u8,
    /// Position of the next input in its block, 0..factor.
    phase: u32,
    /// Blocks completed (saturating): the first `order − 1` give no row.
    blocks: u32,
    /// Partial sums of the outputs in progress, per channel: `acc[k][c]` completes `k`
    /// blocks from now.
    acc: [[f32; 3]; MAX_ORDER as usize],
    /// 1 / factor^order.
    norm: f32,
    /// The compensator's side tap `a` (order / 24), 0.0 without one (factor 1).
    side: f32,
    /// Its centre tap, 1 + 2a.
    middle: f32,
    /// The last two CIC rows, y_{r−1} and y_r.
    cic_rows: [[f32; 3]; 2],
    /// CIC rows held in `cic_rows` since the start (0–2).
    held: u8,
}

impl Decimator {
    /// No decimation: every conversion is a row, unchanged.
    pub const fn none() -> Self {
        Self {
            factor: 1,
            order: 1,
            phase: 0,
            blocks: 0,
            acc: [[0.0; 3]; MAX_ORDER as usize],
            norm: 1.0,
            side: 0.0,
            middle: 1.0,
            cic_rows: [[0.0; 3]; 2],
            held: 0,
        }
    }

    /// `factor` conversions a row, a CIC of `order` (1: the plain mean, as the L4's
    /// hardware oversampler; 3: the F4's software default) and its droop compensator
    /// (`a = order / 24`). With `factor` 1 the order is 1 whatever was asked (every kernel
    /// is one tap) and there is no compensator: each conversion is a row, unchanged.
    pub fn new(factor: u32, order: u8) -> Result<Self, DecimationError> {
        if factor == 0 || factor > MAX_FACTOR {
            return Err(DecimationError::Factor(factor));
        }
        if order == 0 || order > MAX_ORDER {
            return Err(DecimationError::Order(order));
        }
        let order = if factor == 1 { 1 } else { order };
        let mut norm = 1.0f32;
        for _ in 0..order {
            norm *= factor as f32;
        }
        let side = if factor == 1 {
            0.0
        } else {
            f32::from(order) / 24.0
        };
        Ok(Self {
            factor,
            order,
            phase: 0,
            blocks: 0,
            acc: [[0.0; 3]; MAX_ORDER as usize],
            norm: 1.0 / norm,
            side,
            middle: 1.0 + 2.0 * side,
            cic_rows: [[0.0; 3]; 2],
            held: 0,
        })
    }

    /// Conversions a row.
    pub fn factor(&self) -> u32 {
        self.factor
    }

    /// The CIC order.
    pub fn order(&self) -> u8 {
        self.order
    }

    /// Whether the rows go through the droop compensator (every factor above 1).
    pub fn compensated(&self) -> bool {
        self.side != 0.0
    }

    /// The compensator's side tap `a` (order / 24; 0 without a compensator).
    pub fn side_tap(&self) -> f32 {
        self.side
    }

    /// Where row `r` sits, in ADC conversions after `r·factor` (the kernel's centre):
    /// `(N − 1)·D + (D − 1)·(1 − N/2)` for order N, plus D for the compensator's row of
    /// latency (row `r` is the compensated CIC row `r + 1`).
    pub fn centre(&self) -> f64 {
        let d = f64::from(self.factor);
        let n = f64::from(self.order);
        let latency = if self.compensated() { d } else { 0.0 };
        (n - 1.0) * d + (d - 1.0) * (1.0 - n / 2.0) + latency
    }

    /// Blocks of `factor` conversions from the first one to the end of row 0: the CIC's
    /// `order`, and 2 more with the compensator (it needs the CIC rows either side of the
    /// one it compensates, and drops the first). Row `r` completes with conversion
    /// `(r + warm_up)·factor − 1`.
    pub fn warm_up(&self) -> u32 {
        u32::from(self.order) + if self.compensated() { 2 } else { 0 }
    }

    /// The time of row 0 in seconds, the ADC converting at `adc_hz` from t = 0: row `r` is
    /// at `r · factor / adc_hz` plus this.
    pub fn time_offset(&self, adc_hz: f64) -> f64 {
        self.centre() / adc_hz
    }

    /// The amplitude response at `f_hz` of the CIC and its compensator, the ADC converting
    /// at `adc_hz`: `|sinc_D(f)|^N · (1 + 2a(1 − cos(2π f D / f_adc)))`.
    pub fn gain_at(&self, f_hz: f64, adc_hz: f64) -> f64 {
        let d = f64::from(self.factor);
        let a = core::f64::consts::PI * f_hz / adc_hz;
        let s = libm::sin(a);
        let one = if libm::fabs(s) < 1e-300 {
            1.0
        } else {
            libm::sin(a * d) / (d * s)
        };
        let side = f64::from(self.side);
        let compensator = 1.0 + 2.0 * side * (1.0 - libm::cos(2.0 * a * d));
        libm::pow(libm::fabs(one), f64::from(self.order)) * compensator
    }

    /// Drops the rows in progress (after a gap in the conversions, e.g. a sleep).
    pub fn restart(&mut self) {
        self.phase = 0;
        self.blocks = 0;
        self.acc = [[0.0; 3]; MAX_ORDER as usize];
        self.cic_rows = [[0.0; 3]; 2];
        self.held = 0;
    }

    /// The weights (integers, exact in f32) of an input at `phase` in the outputs that
    /// complete 0, 1 and 2 blocks from now.
    fn weights(&self, phase: u32) -> [f32; 3] {
        let d = self.factor;
        let p = phase;
        match self.order {
            1 => [1.0, 0.0, 0.0],
            2 => [(d - p) as f32, p as f32, 0.0],
            _ => {
                let w0 = (d - p) * (d - p + 1) / 2;
                let w2 = if p >= 1 { (p - 1) * p / 2 } else { 0 };
                [w0 as f32, (d * d - w0 - w2) as f32, w2 as f32]
            }
        }
    }

    /// Takes one conversion (x, v, u; an absent channel as 0.0) and returns a row when
    /// this conversion completes one. A NaN input makes the rows it weighs in NaN (the
    /// CIC rows it is in and, through the compensator, the rows either side of them; the
    /// identifier rejects them as a gap).
    pub fn push(&mut self, values: [f32; 3]) -> Option<[f32; 3]> {
        self.push_channels(values, 3)
    }

    /// [`Decimator::push`] of the first `channels` (1–3) values only: the others come out
    /// as 0.0 (an ADC with x only pays for x only).
    #[inline]
    pub fn push_channels(&mut self, values: [f32; 3], channels: usize) -> Option<[f32; 3]> {
        let w = self.weights(self.phase);
        let order = usize::from(self.order);
        let channels = channels.min(3);
        for (acc, &wk) in self.acc.iter_mut().zip(&w).take(order) {
            for (a, &v) in acc.iter_mut().zip(&values).take(channels) {
                *a += wk * v;
            }
        }
        self.phase += 1;
        if self.phase < self.factor {
            return None;
        }
        self.phase = 0;
        let done = self.acc[0];
        // The blocks move down by one (what `rotate_left(1)` did, without its generic
        // memmove: ≈ 100 instructions a row on the M4F, measured under QEMU).
        self.acc[0] = self.acc[1];
        self.acc[1] = self.acc[2];
        if let Some(last) = self.acc.get_mut(order - 1) {
            *last = [0.0; 3];
        }
        self.blocks = self.blocks.saturating_add(1);
        if self.blocks < u32::from(self.order) {
            return None;
        }
        let y = done.map(|a| a * self.norm);
        if self.side == 0.0 {
            return Some(y);
        }
        // The compensator: c_r = (1 + 2a)·y_r − a·(y_{r−1} + y_{r+1}), y_{r+1} the row just
        // completed (in this order of operations, f32, on every target).
        let [before, middle] = self.cic_rows;
        self.cic_rows = [middle, y];
        if self.held < 2 {
            self.held += 1;
            return None;
        }
        let mut out = [0.0f32; 3];
        for (((o, &m), &b), &n) in out
            .iter_mut()
            .zip(&middle)
            .zip(&before)
            .zip(&y)
            .take(channels)
        {
            *o = self.middle * m - self.side * (b + n);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The amplitude of the `f_hz` tone in the rows of a unit sine at `f_hz` through a
    /// decimator (least squares on sin and cos at the rows' instants; an alias shows at
    /// the tone's own frequency sampled at the row rate).
    fn amplitude(d: u32, order: u8, adc_hz: f64, f_hz: f64, n_rows: usize) -> f64 {
        let mut dec = Decimator::new(d, order).unwrap();
        let w = 2.0 * core::f64::consts::PI * f_hz;
        let (mut r, mut i) = (0usize, 0u64);
        let (mut ss, mut sc, mut cc, mut ys, mut yc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        while r < n_rows {
            let x = (w * i as f64 / adc_hz).sin() as f32;
            if let Some(row) = dec.push([x, 0.0, 0.0]) {
                let t = (r as f64 * f64::from(d) + dec.centre()) / adc_hz;
                let (s, c, y) = ((w * t).sin(), (w * t).cos(), f64::from(row[0]));
                ss += s * s;
                sc += s * c;
                cc += c * c;
                ys += y * s;
                yc += y * c;
                r += 1;
            }
            i += 1;
        }
        let det = ss * cc - sc * sc;
        let a = (ys * cc - yc * sc) / det;
        let b = (yc * ss - ys * sc) / det;
        a.hypot(b)
    }

    #[test]
    fn dc_gain_is_one_for_every_order_and_factor() {
        for order in 1..=MAX_ORDER {
            for d in [1, 2, 3, 7, 16, 50, 64, 100, 255] {
                let mut dec = Decimator::new(d, order).unwrap();
                let mut rows = 0;
                for level in [1.0f32, -3.25, 1234.5] {
                    dec.restart();
                    for _ in 0..d * 7 {
                        if let Some(row) = dec.push([level, 2.0 * level, 0.5]) {
                            rows += 1;
                            for (got, want) in row.iter().zip([level, 2.0 * level, 0.5]) {
                                // Rounding of the N·D sums in f32, at most N·D ulps, and
                                // the compensator's three taps.
                                let ulps = (u32::from(order) * d + 3) as f32;
                                assert!(
                                    (got - want).abs() <= ulps * f32::EPSILON * want.abs(),
                                    "order {order}, D {d}: {got} for {want}"
                                );
                            }
                        }
                    }
                }
                // The first order − 1 blocks fill the kernel and the compensator takes two
                // more: 7 − (N + 1) rows a level (7 without decimation).
                let want = if d == 1 {
                    7
                } else {
                    7 - (usize::from(order) + 1)
                };
                assert_eq!(rows, 3 * want, "order {order}, D {d}");
                assert_eq!(dec.warm_up() as usize, 7 - want + 1, "order {order}, D {d}");
            }
        }
    }

    #[test]
    fn an_impulse_weighs_one_conversion_centred_on_its_instant() {
        // An impulse after the warm-up spreads over the rows with weights that add up to
        // one conversion's worth (1/D), centred on the impulse's instant (the kernel is
        // symmetric about `centre`).
        for order in 1..=MAX_ORDER {
            for d in [1u32, 4, 9, 50] {
                // After the first N + 1 blocks: the CIC rows 0 and 1 are the compensator's
                // warm-up (row 0 is not compensated, so its share of row 1 is not output).
                let start = (u32::from(order) + 1) * d;
                for at in start..start + d {
                    let mut dec = Decimator::new(d, order).unwrap();
                    let (mut r, mut sum, mut moment) = (0u32, 0.0f64, 0.0f64);
                    for i in 0..at + (u32::from(order) + 3) * d {
                        if let Some(row) = dec.push([f32::from(u8::from(i == at)), 0.0, 0.0]) {
                            let instant = f64::from(r * d) + dec.centre();
                            sum += f64::from(row[0]);
                            moment += f64::from(row[0]) * instant;
                            r += 1;
                        }
                    }
                    let d = f64::from(d);
                    assert!((sum * d - 1.0).abs() < 1e-6, "order {order}, D {d}: {sum}");
                    // The rows' weighted instant: the impulse's, within the half-row the
                    // block grid allows for order 1 (its kernel is one block).
                    let mean = moment / sum;
                    assert!(
                        (mean - f64::from(at)).abs() <= d / 2.0,
                        "order {order}, D {d}: impulse at {at}, rows' mean instant {mean}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_sine_comes_through_with_the_predicted_gain_and_its_alias_is_attenuated() {
        // 10 kHz conversions, rows at 200 Hz (D = 50): the passband (eveh's 3.4 Hz and its
        // harmonics to 20 Hz) keeps its amplitude within the predicted droop; a 180 Hz
        // tone (folds onto 20 Hz) comes out attenuated by the predicted amount.
        let adc = 10_000.0;
        for order in 1..=MAX_ORDER {
            let dec = Decimator::new(50, order).unwrap();
            for f in [3.4, 10.2, 20.0, 180.0, 390.0, 1234.0] {
                let got = amplitude(50, order, adc, f, 3000);
                let predicted = dec.gain_at(f, adc);
                assert!(
                    (got - predicted).abs() <= 1e-3 * predicted + 1e-5,
                    "order {order}, {f} Hz: amplitude {got}, predicted {predicted}"
                );
            }
            let db = 20.0 * dec.gain_at(180.0, adc).log10();
            println!(
                "order {order}, D 50 at 10 kHz: 3.4 Hz {:.4}, 20 Hz {:.4}, 180 Hz (alias of 20 Hz) {db:.1} dB",
                dec.gain_at(3.4, adc),
                dec.gain_at(20.0, adc)
            );
            let want = [-19.0, -38.0, -57.0][usize::from(order) - 1];
            assert!(db <= want, "order {order}: {db} dB at 180 Hz");
        }
    }

    #[test]
    fn the_compensator_flattens_the_passband_at_the_proposed_rate() {
        // eveh at the rate `lssi identify` proposes: 10 kHz by 47 (212.8 rows/s). The CIC's
        // droop at the cubic's third harmonic (10.2 Hz) and at 20 Hz, against what is left
        // with the compensator, measured on rows through the decimator.
        let adc = 10_000.0;
        for order in 1..=MAX_ORDER {
            let dec = Decimator::new(47, order).unwrap();
            assert_eq!(dec.side_tap(), f32::from(order) / 24.0);
            for f in [3.4, 10.2, 20.0] {
                let x = core::f64::consts::PI * f * 47.0 / adc;
                let droop = 1.0 - (x.sin() / (47.0 * (x / 47.0).sin())).powi(i32::from(order));
                let got = amplitude(47, order, adc, f, 2000);
                let left = (got - 1.0).abs();
                println!(
                    "order {order}, D 47 at 10 kHz, {f} Hz: CIC droop {:.4} %, compensated {:.5} % ({:.5} % predicted)",
                    100.0 * droop,
                    100.0 * left,
                    100.0 * (dec.gain_at(f, adc) - 1.0).abs()
                );
                assert!(
                    (got - dec.gain_at(f, adc)).abs() <= 1e-4,
                    "order {order}, {f} Hz"
                );
                // Second order flattened: what is left is fourth order in f / f_r, under
                // 1/15 of the droop (and under 0.05 % to 10.2 Hz).
                assert!(
                    left <= droop / 15.0,
                    "order {order}, {f} Hz: {left} of {droop}"
                );
                if f <= 10.2 {
                    assert!(left <= 5e-4, "order {order}, {f} Hz: {left}");
                }
            }
        }
    }

    #[test]
    fn rows_sit_at_the_kernel_centre() {
        // A ramp x = i comes out as the centre's index: the times are right.
        for order in 1..=MAX_ORDER {
            for d in [1u32, 5, 50] {
                let mut dec = Decimator::new(d, order).unwrap();
                let mut r = 0u32;
                for i in 0..d * 20 {
                    if let Some(row) = dec.push([i as f32, 0.0, 0.0]) {
                        let want = f64::from(r * d) + dec.centre();
                        assert!(
                            (f64::from(row[0]) - want).abs() <= 1e-3 * want.max(1.0),
                            "order {order}, D {d}, row {r}: {} for {want}",
                            row[0]
                        );
                        r += 1;
                    }
                }
            }
        }
    }

    #[test]
    fn bad_settings_are_refused_with_a_reason() {
        assert_eq!(Decimator::new(0, 1), Err(DecimationError::Factor(0)));
        assert_eq!(Decimator::new(256, 1), Err(DecimationError::Factor(256)));
        assert_eq!(Decimator::new(4, 0), Err(DecimationError::Order(0)));
        assert_eq!(Decimator::new(4, 4), Err(DecimationError::Order(4)));
        assert!(DecimationError::Factor(0).to_string().contains("1 to 255"));
    }

    #[test]
    fn the_factor_is_the_nearest_integer_ratio() {
        assert_eq!(factor_for(10_000.0, 1.0 / 200.0), Some(50));
        assert_eq!(factor_for(10_000.0, 1.0 / 10_000.0), Some(1));
        assert_eq!(factor_for(10_000.0, 1.0 / 300.0), None); // 33.3
        assert_eq!(factor_for(10_000.0, 1.0 / 20.0), None); // 500 > 255
        assert_eq!(factor_for(10_000.0, f64::NAN), None);
        assert_eq!(factor_for(1000.0, 1.0 / 1e6), None);
    }
}
