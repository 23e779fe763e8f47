//! Truth simulators (helper is writing this module).
