//! Signal processing shared by the rig path and the time-domain path: IIR low-pass filters
//! and zero-phase filtering ([`iir`]), the validation's zero-phase low-pass and the sensor
//! low-pass model ([`lowpass`]), central differences and the band-limited derivative ([`differentiate`]), MATLAB-style
//! decimation ([`decimate`]), a shift by a fraction of a sample ([`delay`]), FFT plans remembered by length ([`fft`]) and the Bouc-Wen hysteretic state ([`bouc_wen`]).
//!
//! Pure functions of sampled data, as the rest of the crate. Where two users need the same
//! thing computed in different ways (two zero-phase filter designs, two rounding orders of a
//! central difference, two Bouc-Wen integrators), both are kept here under their own names,
//! each with a doc comment saying why it exists: their outputs differ in the last bits or more,
//! and replacing one by the other would change published figures or test results.

pub mod bouc_wen;
pub mod decimate;
pub mod delay;
pub mod differentiate;
pub mod fft;
pub mod iir;
pub mod lowpass;
