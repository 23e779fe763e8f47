//! forcemap_io: the file formats and data plumbing of forcemap, with no ROS runtime and no
//! async: rosbag2 MCAP bags, test-bench CSV exports, the EMPS MAT import, ROS 2 params files,
//! the assembly of samples into step records, topic names, atomic writes and records kept in a
//! temporary file. The nodes and the command build on it; it builds on `forcemap_math` and
//! `forcemap_msgs` only.
pub mod atomic;
pub mod axis;
pub mod bag;
pub mod channel_map;
pub mod csv_export;
pub mod distro;
pub mod emps;
pub mod foreign_bag;
pub mod foreign_topics;
pub mod input;
pub mod mdf;
pub mod messages;
pub mod params;
pub mod rig_bag;
pub mod rig_constants;
pub mod rig_messages;
pub mod ros_msg;
pub mod spill;
pub mod stamp_align;
pub mod steps;
pub mod table;
pub mod table_map;
pub mod tabular;
pub mod tdms;
pub mod topics;
pub mod units;
