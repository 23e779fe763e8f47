//! The ROS 2 distribution forcemap is built for.

/// The ROS 2 distribution forcemap is built for (cargo feature `jazzy`, the default, or
/// `humble`): the nodes speak its wire format (e.g. 16- or 24-byte GIDs) and bags name it in
/// their metadata when no ROS 2 environment is sourced.
pub const BUILT_FOR_DISTRO: &str = if cfg!(feature = "jazzy") {
    "jazzy"
} else if cfg!(feature = "humble") {
    "humble"
} else {
    ""
};
