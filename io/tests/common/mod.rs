//! Helpers shared by forcemap_io's integration tests.
#![allow(dead_code)]

mod python;
pub use python::python_bag_check;
