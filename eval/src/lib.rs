//! forcemap_eval: the evaluation harnesses of forcemap, kept out of the library's build.
//!
//! - [`paper`]: the reference numbers of W.-J. Kim (1997), Tables 1-4, and the truths forcemap
//!   simulates against.
//! - [`reproduce`]: Tables 1-4 reproduced (the paper's numbers, the truth and forcemap's side by
//!   side), behind `forcemap reproduce`.
//! - [`diagnose_eval`]: the gap diagnosis checked on withheld effects (planted-effect cases,
//!   scoring, summary), behind `forcemap diagnose-eval`.
//!
//! Like the mathematics it builds on (`forcemap_math`), no I/O, no async, no ROS.

pub mod diagnose_eval;
pub mod paper;
pub mod reproduce;
