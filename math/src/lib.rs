//! forcemap_math: the mathematics of frequency-domain force-state mapping (FD-FSM).
//!
//! No I/O, no async, no ROS: everything here is a pure function of its inputs so it can be
//! read, tested and benchmarked alone. File formats (`forcemap_io`), the ROS 2 nodes
//! (`forcemap_nodes`) and the `forcemap` command (`forcemap_cli`) are built on it.
//!
//! Sign and phasor conventions used throughout:
//! - The element force `g(x, x')` acts between its two ends; `x` is the relative
//!   displacement across it. For the base-excited rig `m x_o'' = -g(x, x')` with
//!   `x = x_o - x_i` (mass minus base).
//! - A phasor `C_n` of a real periodic signal is one-sided: `s(t) = Re(sum_{n>=0} C_n e^{j n w (t - t_ref)})`,
//!   so `|C_1|` is the amplitude of the fundamental and `C_0` is the mean.

pub mod basis;
pub mod diagnose;
pub mod dynamic_stiffness;
pub mod element;
pub mod frf;
pub mod identify;
pub mod lstsq;
pub mod measured_state;
pub mod model;
pub mod parallel;
pub mod phasor;
pub mod pipeline;
pub mod recipe;
pub mod record;
pub mod segment;
pub mod signal;
pub mod sim;
