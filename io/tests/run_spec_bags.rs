//! The paper's runs as `RunSpec`s simulate to the records of the committed sample bags in
//! bags/ (written by `forcemap simulate`, see bags/regenerate.sh), sample for sample.

use std::path::{Path, PathBuf};

use forcemap_io::rig_bag::read_rig_bag;
use forcemap_math::record::Record;
use forcemap_math::sim::{RunSpec, ThreeDofCase};

fn bag(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../bags")
        .join(name)
}

fn assert_same_samples(name: &str, simulated: &[Record], from_bag: &[Record]) {
    assert_eq!(simulated.len(), from_bag.len(), "{name}: record count");
    for (s, b) in simulated.iter().zip(from_bag) {
        assert_eq!(s.step, b.step, "{name}");
        assert_eq!(s.excitation, b.excitation, "{name}: step {}", s.step);
        assert_eq!(s.len(), b.len(), "{name}: step {} length", s.step);
        for (c, v) in &s.channels {
            let w = b
                .channel(*c)
                .unwrap_or_else(|| panic!("{name}: step {}: no {c:?} in the bag", s.step));
            for (i, (x, y)) in v.iter().zip(w).enumerate() {
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "{name}: step {}, {c:?}[{i}]: {x} simulated, {y} in the bag",
                    s.step
                );
            }
        }
    }
}

#[test]
fn the_paper_rig_run_is_the_committed_rig_bag() {
    let records = RunSpec::paper_rig(Some(40.0), 1).simulate().unwrap();
    let from_bag = read_rig_bag(&bag("rig_40db")).unwrap();
    assert_eq!(from_bag.parameters.get("mass_kg"), Some(&36.0));
    assert_same_samples("rig_40db", &records, &from_bag.records);
}

#[test]
fn the_three_dof_cases_are_the_committed_bags() {
    for (case, name) in [
        (ThreeDofCase::I, "three_dof_case_i"),
        (ThreeDofCase::Ii, "three_dof_case_ii"),
    ] {
        let records = RunSpec::three_dof(case, None, 0).simulate().unwrap();
        assert_same_samples(name, &records, &read_rig_bag(&bag(name)).unwrap().records);
    }
}
