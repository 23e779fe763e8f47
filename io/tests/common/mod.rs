//! Helpers shared by forcemap_io's integration tests.
#![allow(dead_code)]

mod python;
#[allow(unused_imports, reason = "used by the bag tests only")]
pub use python::python_bag_check;

/// The damper dyno's identification as `forcemap identify` runs it: the `damper` model by
/// fd-multi with the default options, the fixture's 0.8 kg moving mass known.
pub fn dyno_identification(
    records: &[forcemap_math::record::Record],
) -> forcemap_math::identify::Identification {
    use forcemap_math::identify::{FdMultiOptions, Method};
    use forcemap_math::model::{Model, ModelOptions};
    use forcemap_math::phasor::PhasorOptions;
    use forcemap_math::recipe::Setup;
    let model = Model::by_name("damper", &ModelOptions::default()).expect("a built-in model");
    forcemap_math::pipeline::identify_records(
        &model,
        &Setup::Element {
            moving_mass_kg: Some(0.8),
            drive: None,
        },
        Method::FdMulti,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .expect("the dyno run identifies")
}
