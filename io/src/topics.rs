//! The topics of a rig: one name each, relative to the rig's namespace (what the nodes
//! create, so `/rig/samples` in namespace `/rig`) and absolute under the default namespace
//! `/rig` (what the sensor's bags hold).

/// The namespace of a rig's topics in forcemap's own bags and launch files.
pub const RIG_NAMESPACE: &str = "/rig";

/// Defines a topic's relative name and its absolute name under [`RIG_NAMESPACE`] from one
/// literal, so the two cannot drift apart.
macro_rules! rig_topic {
    ($(#[$doc:meta])* $relative:ident, $absolute:ident, $name:literal) => {
        $(#[$doc])*
        pub const $relative: &str = $name;
        $(#[$doc])*
        pub const $absolute: &str = concat!("/rig/", $name);
    };
}

rig_topic!(
    /// One `forcemap_msgs/msg/RigSample` per sample.
    SAMPLES, RIG_SAMPLES, "samples"
);
rig_topic!(
    /// One `forcemap_msgs/msg/ExcitationState` per step (transient local).
    EXCITATION, RIG_EXCITATION, "excitation"
);
rig_topic!(
    /// Rig constants (`mass_kg`, ...) as a `diagnostic_msgs/msg/DiagnosticStatus`.
    PARAMETERS, RIG_PARAMETERS, "parameters"
);
rig_topic!(
    /// One `forcemap_msgs/msg/HarmonicPhasors` per settled step.
    PHASORS, RIG_PHASORS, "phasors"
);
rig_topic!(
    /// `forcemap_msgs/msg/HarmonicPhasors` of the step in progress (the harmonic node's
    /// `update_period_s`): provisional, each replaced by the next or by the step's phasors.
    PROVISIONAL_PHASORS, RIG_PROVISIONAL_PHASORS, "phasors/provisional"
);
rig_topic!(
    /// The identifier's `forcemap_msgs/msg/IdentifiedParameters`.
    THETA, RIG_THETA, "theta"
);
rig_topic!(
    /// The diagnoser's `forcemap_msgs/msg/GapDiagnosis`.
    DIAGNOSIS, RIG_DIAGNOSIS, "diagnosis"
);

/// The ROS 2 diagnostics topic (absolute in every namespace).
pub const DIAGNOSTICS: &str = "/diagnostics";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absolute_names_are_the_relative_names_under_the_rig_namespace() {
        for (rel, abs) in [
            (SAMPLES, RIG_SAMPLES),
            (EXCITATION, RIG_EXCITATION),
            (PARAMETERS, RIG_PARAMETERS),
            (PHASORS, RIG_PHASORS),
            (PROVISIONAL_PHASORS, RIG_PROVISIONAL_PHASORS),
            (THETA, RIG_THETA),
            (DIAGNOSIS, RIG_DIAGNOSIS),
        ] {
            assert_eq!(abs, format!("{RIG_NAMESPACE}/{rel}"));
        }
    }
}
