use super::*;
use crate::{Channels, ConfigError, LibraryConfig, PolyFamily};

/// x and a measured v; x and a measured u.
const XV: Channels = Channels {
    velocity: true,
    input: false,
};
const XU: Channels = Channels {
    velocity: false,
    input: true,
};

/// The forced Duffing oscillator x'' = −400x − 2x' − 4·10⁴x³ + u, u = 60 cos(15t), 1 ms
/// samples of (t, x, v, u) (`lssi_testkit::duffing`).
fn duffing(n: usize) -> impl Iterator<Item = (f64, f64, f64, f64)> {
    lssi_testkit::duffing(n)
        .into_iter()
        .map(|p| (p.t, p.x, p.v, p.u))
}

fn config(channels: Channels) -> Config {
    Config {
        sample_period: 1e-3,
        window: 63,
        library: LibraryConfig {
            poly_order: 3,
            family: PolyFamily::All,
            constant: true,
            harmonics: if channels.input { 0 } else { 1 },
            input: channels.input,
        },
        omega: 15.0,
        channels,
        screening_period: 5_000,
        ..Config::default()
    }
}

/// Everything a model says, floats as bits.
fn bits<const P: usize>(m: &Model<f32, P>) -> Vec<u64> {
    let mut out: Vec<u64> = m
        .coefficients
        .iter()
        .map(|c| u64::from(c.to_bits()))
        .collect();
    for s in m.solutions.iter() {
        out.extend([
            u64::from(s.threshold.to_bits()),
            u64::from(s.mean_error.to_bits()),
            u64::from(s.support),
        ]);
    }
    out.extend([
        m.terms.len() as u64,
        m.selected as u64,
        u64::from(m.k.0),
        u64::from(m.k.1),
        u64::from(m.offset_x.to_bits()),
        u64::from(m.offset_v.to_bits()),
        m.samples,
        m.rejected,
        m.rows,
    ]);
    out
}

/// Every model of the recording (each scheduled screening's, then one on request).
fn models<const C: usize>(channels: Channels, n: usize) -> Vec<Vec<u64>> {
    let Ok(mut id) = Identifier::<f32, 128, 16, C>::new(config(channels)) else {
        panic!("the configuration fits C = {C}");
    };
    models_of(&mut id, channels, n)
}

/// Every model `id` gives on the recording.
fn models_of<const C: usize>(
    id: &mut Identifier<f32, 128, 16, C>,
    channels: Channels,
    n: usize,
) -> Vec<Vec<u64>> {
    let mut out = Vec::new();
    for (t, x, v, u) in duffing(n) {
        let sample = Sample {
            t,
            x: x as f32,
            v: channels.velocity.then_some(v as f32),
            u: channels.input.then_some(u as f32),
        };
        if id.push(sample) == Ok(true) {
            out.push(bits(id.model().expect("a screening made it")));
        }
    }
    assert!(id.screen());
    out.push(bits(id.model().expect("a model")));
    out
}

/// Test-function rows (`Config::test_rows`): the Duffing oscillator from x and u, with
/// a row every sample summed over a third of the period, comes out within 1 %; and an
/// identifier switched between sums and rows as they are (the block factor and the sums
/// share their memory) gives the models of a new one, bit for bit, both ways.
#[test]
fn test_function_rows_identify_and_switch_cleanly() {
    let sums = |channels| Config {
        window: 9,
        derivative_degree: 5,
        row_stride: 1,
        test_rows: 140,
        ..config(channels)
    };
    let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(sums(XU)) else {
        panic!("valid");
    };
    let with_sums = models_of(&mut id, XU, 12_000);
    let model = id.model().expect("a model");
    for (term, truth) in [
        (Term::Monomial { px: 1, pv: 0 }, -400.0),
        (Term::Monomial { px: 0, pv: 1 }, -2.0),
        (Term::Monomial { px: 3, pv: 0 }, -4.0e4),
        (Term::Input, 1.0),
    ] {
        let c = f64::from(model.coefficient(term).unwrap_or(0.0));
        assert!(
            (c / truth - 1.0).abs() < 0.01,
            "{term:?}: {c} against {truth}"
        );
    }
    // Sums, then rows as they are, in place: the models of a new identifier.
    assert!(id.reconfigure(config(XV)).is_ok());
    assert_eq!(models_of(&mut id, XV, 12_000), models::<3>(XV, 12_000));
    // And back.
    assert!(id.reconfigure(sums(XU)).is_ok());
    assert_eq!(models_of(&mut id, XU, 12_000), with_sums);
}

#[test]
fn configured_in_place_gives_the_models_of_new_bit_for_bit() {
    let reference = models::<3>(XV, 12_000);
    // A slot, configured first for something else (x and u, a shorter window, no
    // harmonics, forgetting) and run, then configured again in place.
    let mut slot: Box<IdentifierSlot<f32, 128, 16, 3>> = Box::default();
    assert!(slot.get().is_none());
    let other = Config {
        window: 41,
        memory: Some(2.0),
        ..config(XU)
    };
    let Ok(id) = slot.configure(other) else {
        panic!("the other configuration is valid");
    };
    assert_eq!(models_of(id, XU, 11_000).len(), 3);
    // A refused configuration changes nothing: the slot keeps its identifier and state.
    let counters = *id.counters();
    let bad = Config {
        window: 129,
        ..config(XV)
    };
    assert!(slot.configure(bad).is_err());
    let Some(id) = slot.get_mut() else {
        panic!("still configured");
    };
    assert_eq!((*id.config(), *id.counters()), (other, counters));
    let Ok(id) = slot.configure(config(XV)) else {
        panic!("valid");
    };
    assert!(id.model().is_none());
    assert_eq!(id.counters(), &Counters::default());
    assert_eq!(models_of(id, XV, 12_000), reference);
    // `reconfigure` on a used identifier, and `new` on top of the same path.
    let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(other) else {
        panic!("valid");
    };
    let _ = models_of(&mut id, XU, 7_000);
    assert!(id.reconfigure(bad).is_err());
    assert_eq!(id.config(), &other);
    assert!(id.reconfigure(config(XV)).is_ok());
    assert_eq!(models_of(&mut id, XV, 12_000), reference);
}

/// `forget` keeps the configuration and its taps and forgets the rest: a used identifier
/// (rows as they are, with forgetting; then test-function sums) forgotten gives the models of
/// a new one, bit for bit, and a second time too (the sums' bump kept).
#[test]
fn forgotten_gives_the_models_of_new_bit_for_bit() {
    let sums = Config {
        window: 9,
        derivative_degree: 5,
        row_stride: 1,
        test_rows: 140,
        ..config(XU)
    };
    let forgetting = Config {
        window: 41,
        memory: Some(2.0),
        ..config(XV)
    };
    for config in [config(XV), forgetting, sums] {
        let channels = config.channels;
        let Ok(mut fresh) = Identifier::<f32, 128, 16, 3>::new(config) else {
            panic!("valid");
        };
        let reference = models_of(&mut fresh, channels, 12_000);
        let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(config) else {
            panic!("valid");
        };
        let _ = models_of(&mut id, channels, 7_000);
        id.forget();
        assert!(id.model().is_none());
        assert_eq!(id.counters(), &Counters::default());
        assert_eq!(models_of(&mut id, channels, 12_000), reference);
        id.forget();
        assert_eq!(models_of(&mut id, channels, 12_000), reference);
    }
}

#[test]
fn an_empty_slot_is_not_configured() {
    let mut slot: Box<IdentifierSlot<f64, 64, 8, 1>> = Box::default();
    assert!(slot.get().is_none() && slot.get_mut().is_none());
    let bad = Config {
        window: 65,
        ..Config::default()
    };
    assert!(slot.configure(bad).is_err());
    assert!(slot.get().is_none());
}

#[test]
fn more_channels_than_rings_are_refused() {
    let all = Channels {
        velocity: true,
        input: true,
    };
    let expected = ConfigError::Channels {
        channels: 3,
        capacity: 2,
    };
    assert_eq!(config(all).validate::<128, 16, 2>(), Err(expected));
    assert_eq!(
        Identifier::<f32, 128, 16, 2>::new(config(all)).err(),
        Some(expected)
    );
    assert_eq!(
        expected.to_string(),
        "the samples carry 3 channels (x, and v and u when measured), but this identifier \
         was built with ring buffers for 2"
    );
    assert!(Identifier::<f32, 128, 16, 3>::new(config(all)).is_ok());
    assert!(Identifier::<f32, 128, 16, 2>::new(config(XV)).is_ok());
    assert_eq!(
        Identifier::<f32, 128, 16, 1>::new(config(XV)).err(),
        Some(ConfigError::Channels {
            channels: 2,
            capacity: 1
        })
    );
    assert!(Identifier::<f32, 128, 16, 1>::new(config(Channels::default())).is_ok());
}

#[test]
fn two_rings_give_the_models_of_three_bit_for_bit() {
    for channels in [XV, XU] {
        let three = models::<3>(channels, 20_000);
        assert_eq!(three.len(), 5, "{channels:?}");
        assert_eq!(models::<2>(channels, 20_000), three, "{channels:?}");
    }
    let x = Channels::default();
    assert_eq!(models::<1>(x, 12_000), models::<3>(x, 12_000));
}

/// Every model of the recording with each screening run on a snapshot (taken at the
/// scheduled point, screened at once here; on a device later, elsewhere).
fn deferred_models(config: Config, channels: Channels, n: usize) -> Vec<Vec<u64>> {
    let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(config) else {
        panic!("valid");
    };
    let mut snapshot: Box<Snapshot<f32, 16>> = Box::new(Snapshot::empty());
    let mut out = Vec::new();
    for (t, x, v, u) in duffing(n) {
        let sample = Sample {
            t,
            x: x as f32,
            v: channels.velocity.then_some(v as f32),
            u: channels.input.then_some(u as f32),
        };
        let mut taken = false;
        let pushed = id.push_with(sample, |id| {
            id.snapshot_into(&mut snapshot);
            taken = true;
            false
        });
        assert_eq!(
            pushed,
            Ok(false),
            "a deferred screening makes no model in place"
        );
        if taken && snapshot.select() {
            out.push(bits(snapshot.model().expect("a screening made it")));
        }
    }
    assert!(id.model().is_none());
    // The screening on request at the end, on a snapshot too.
    id.snapshot_into(&mut snapshot);
    assert!(snapshot.select());
    out.push(bits(snapshot.model().expect("a model")));
    out
}

/// A screening on a snapshot gives the model of the screening in place, bit for bit, at
/// every scheduled point and at the end: rows as they are (x and v, where the smoothing's
/// K is re-chosen after each screening) and test-function sums (x and u).
#[test]
fn snapshot_screenings_give_the_models_of_screenings_in_place() {
    assert_eq!(
        deferred_models(config(XV), XV, 24_000),
        models::<3>(XV, 24_000)
    );
    let sums = Config {
        window: 9,
        derivative_degree: 5,
        row_stride: 1,
        test_rows: 140,
        ..config(XU)
    };
    let Ok(mut id) = Identifier::<f32, 128, 16, 3>::new(sums) else {
        panic!("valid");
    };
    let inline = models_of(&mut id, XU, 12_000);
    assert!(inline.len() >= 3, "{} models", inline.len());
    assert_eq!(deferred_models(sums, XU, 12_000), inline);
}
