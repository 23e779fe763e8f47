//! Errors of the harmonic analysis name the step, the channel and the sample.

use forcemap_math::phasor::{PhasorError, PhasorOptions, analyse_record, fit_harmonics};
use forcemap_math::record::{Channel, Excitation, Record};

fn sine_record(len: usize, f: f64) -> Record {
    let x: Vec<f64> = (0..len)
        .map(|k| (2.0 * std::f64::consts::PI * f * k as f64 / 100.0).sin())
        .collect();
    Record {
        step: 4,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 0.01,
        },
        sample_rate_hz: 100.0,
        start_time_s: 0.0,
        channels: vec![
            (Channel::ForceN, x.clone()),
            (Channel::RelativeDisplacementM, x),
        ],
    }
}

#[test]
fn nan_sample_names_channel_and_index() {
    let mut r = sine_record(1300, 1.6);
    r.channel_mut(Channel::RelativeDisplacementM).unwrap()[417] = f64::NAN;
    let e = analyse_record(&r, &PhasorOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            PhasorError::NonFinite {
                step: 4,
                channel: Channel::RelativeDisplacementM,
                sample: 417,
                ..
            }
        ),
        "{e:?}"
    );
    let msg = e.to_string();
    assert!(
        msg.contains("step 4")
            && msg.contains("RelativeDisplacementM")
            && msg.contains("sample 417"),
        "{msg}"
    );
    r.channel_mut(Channel::RelativeDisplacementM).unwrap()[417] = 0.0;
    r.channel_mut(Channel::ForceN).unwrap()[3] = f64::NEG_INFINITY;
    let e = analyse_record(&r, &PhasorOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            PhasorError::NonFinite {
                channel: Channel::ForceN,
                sample: 3,
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn too_short_record() {
    // 1.6 Hz at 100 Hz: two whole periods need 125 samples.
    assert!(analyse_record(&sine_record(125, 1.6), &PhasorOptions::default()).is_ok());
    let e = analyse_record(&sine_record(124, 1.6), &PhasorOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            PhasorError::TooShort {
                step: 4,
                samples: 124,
                needed: 125,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("step 4"), "{e}");
}

#[test]
fn random_record() {
    let mut r = sine_record(1300, 1.6);
    r.excitation = Excitation::Random {
        band_hz: Some([0.5, 20.0]),
        rms: 0.01,
    };
    let e = analyse_record(&r, &PhasorOptions::default()).unwrap_err();
    assert_eq!(e, PhasorError::NotSine { step: 4 });
    assert!(e.to_string().contains("step 4"));
}

#[test]
fn bad_frequency_and_lengths() {
    let o = PhasorOptions::default();
    for (f, want) in [
        (0.0, "not a positive"),
        (-1.0, "not a positive"),
        (f64::NAN, "not a positive"),
        (50.0, "Nyquist"),
        (70.0, "Nyquist"),
        (40.0, "samples per period"),
    ] {
        let mut r = sine_record(1300, 1.6);
        r.excitation = Excitation::Sine {
            frequency_hz: f,
            amplitude: 1.0,
        };
        let e = analyse_record(&r, &o).unwrap_err();
        assert!(e.to_string().contains(want), "f = {f}: {e}");
    }
    let mut r = sine_record(1300, 1.6);
    r.channel_mut(Channel::RelativeDisplacementM).unwrap().pop();
    let e = analyse_record(&r, &o).unwrap_err();
    assert!(
        matches!(
            e,
            PhasorError::ChannelLengthMismatch {
                step: 4,
                channel: Channel::RelativeDisplacementM,
                len: 1299,
                expected: 1300,
                ..
            }
        ),
        "{e:?}"
    );
    r.channels.clear();
    assert_eq!(
        analyse_record(&r, &o).unwrap_err(),
        PhasorError::NoChannels { step: 4 }
    );
}

#[test]
fn fit_harmonics_rejects_bad_input() {
    let x = vec![0.0; 10];
    assert!(fit_harmonics(&x, 100.0, 10.0, 5).is_err()); // 5 * 10 Hz = Nyquist
    assert!(fit_harmonics(&x, 100.0, 1.0, 5).is_err()); // 10 samples < 11 parameters
    assert!(fit_harmonics(&x, 100.0, 0.0, 1).is_err());
    assert!(fit_harmonics(&[0.0, 1.0, f64::NAN, 0.0], 100.0, 25.0, 1).is_err());
    assert!(fit_harmonics(&x, 100.0, 10.0, 4).is_ok());
}
