//! forcemap_nodes: the `forcemap` command and (later) the ROS 2 nodes, thin adapters around
//! `forcemap_math`.
pub mod bag;
pub mod cli;
pub mod commands;
pub mod csv_export;
pub mod emps;
pub mod input;
pub mod launch;
pub mod node;
pub mod params;
pub mod plot;
pub mod rig_bag;
pub mod ros;
pub mod steps;
