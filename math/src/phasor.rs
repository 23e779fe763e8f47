//! Harmonic analysis (helper is writing this module).
