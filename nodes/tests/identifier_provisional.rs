//! The identifier's handling of provisional phasors, on the committed rig bag's steps:
//! provisional phasors never enter the equations (a converged identifier publishes the same
//! finals bit for bit with or without them), a step's provisional theta with all its periods in
//! is its final theta (and its status the final one's, marked provisional), and every theta is
//! stamped with the end of its newest step's data.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_nodes::node::identifier::Input;

mod common;

use common::*;

#[test]
fn a_provisional_step_with_all_its_periods_in_gives_the_final_theta() {
    for factor in [1.0, 0.7] {
        let mut c = rig_core(factor);
        for ph in phasor_messages() {
            // The step's phasors as provisional ones: the theta the final ones will give...
            let provisional = c.handle_provisional(&ph);
            let final_ = c
                .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
                .unwrap();
            let (p, f) = (thetas(&provisional), thetas(&final_));
            assert_eq!((p.len(), f.len()), (1, 1), "step {}", ph.step);
            assert_eq!(p[0].values, f[0].values, "step {}", ph.step);
            assert_eq!(p[0].covariance, f[0].covariance);
            assert_eq!(p[0].header.stamp, f[0].header.stamp);
            // Its /diagnostics status is the final one's, marked provisional.
            let (ps, fs) = (statuses(&provisional), statuses(&final_));
            assert_eq!((ps.len(), fs.len()), (1, 1), "step {}", ph.step);
            assert_eq!(ps[0].level, fs[0].level, "{:?} {:?}", ps[0], fs[0]);
            assert_eq!(ps[0].name, fs[0].name);
            let value = |k: &str| {
                ps[0]
                    .values
                    .iter()
                    .find(|v| v.key == k)
                    .map(|v| v.value.clone())
            };
            assert_eq!(value("provisional_step"), Some(ph.step.to_string()));
            assert_eq!(
                value("provisional_periods"),
                Some(ph.periods_used.to_string())
            );
            assert_eq!(
                value("recipe"),
                fs[0]
                    .values
                    .iter()
                    .find(|v| v.key == "recipe")
                    .map(|v| v.value.clone())
            );
            // ...and once the step is in, its phasors are never added again.
            assert!(c.handle_provisional(&ph).is_empty(), "step {}", ph.step);
        }
    }
}

#[test]
fn provisional_phasors_leave_the_equations_as_they_are() {
    let finals = phasor_messages();
    for factor in [1.0, 0.7] {
        let mut plain = rig_core(factor);
        let mut with = rig_core(factor);
        for (j, ph) in finals.iter().enumerate() {
            let a = plain
                .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
                .unwrap();
            // Before each step, provisional phasors (another step's, renumbered as this one).
            let mut stand_in = finals[(j + 3) % finals.len()].clone();
            stand_in.step = ph.step;
            stand_in.t_ref = ph.t_ref;
            assert!(!thetas(&with.handle_provisional(&stand_in)).is_empty() || j == 0);
            let b = with
                .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
                .unwrap();
            assert_eq!(thetas(&a), thetas(&b), "step {}", ph.step);
            assert_eq!(plain.state(), with.state());
        }
    }
}

/// Every theta is stamped with the end of its newest step's data, whatever the clock says.
#[test]
fn theta_is_stamped_with_the_end_of_its_data() {
    let mut c = rig_core(1.0);
    for ph in phasor_messages() {
        let o = c
            .handle(Input::Phasors(Box::new(ph.clone())), RUN_START)
            .unwrap();
        let end = ph
            .t_ref
            .add_secs_f64(f64::from(ph.periods_used) / ph.frequency_hz);
        assert_eq!(thetas(&o)[0].header.stamp, end);
        assert_eq!(forcemap_nodes::node::identifier::data_end_time(&ph), end);
    }
}
