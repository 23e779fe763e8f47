//! forcemap_cli: the `forcemap` command (argument parsing, one module per subcommand, plots
//! and HTML reports) on top of `forcemap_math`, `forcemap_io` and `forcemap_nodes`.
pub mod cli;
pub mod commands;
pub mod plot;
pub mod report;
