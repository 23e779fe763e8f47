//! forcemap_nodes: forcemap's ROS 2 nodes, each a process (`forcemap node KIND`), and the
//! launcher that starts a graph of them from a ROS 2 YAML launch file. The nodes are thin
//! shells on ros2-client and tokio around `forcemap_math` and `forcemap_io`.
pub mod latency_trace;
pub mod launch;
pub mod node;
pub mod parameter_services;
pub mod ros;
