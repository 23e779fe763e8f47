//! Identification on the simulated rig stand-in (truth: the paper's Coulomb values), checked
//! against the truth of the simulation and against the paper's qualitative findings.
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]

use forcemap_eval::paper::RIG_TRUTH;
use forcemap_eval::reproduce::{RigData, Row, rig_data, rig_row};
use forcemap_math::identify::Method;
use forcemap_math::sim::TruthElement;
use std::sync::OnceLock;

fn data_40db() -> &'static RigData {
    static D: OnceLock<RigData> = OnceLock::new();
    D.get_or_init(|| rig_data(TruthElement::rig_coulomb(), Some(40.0), 7).expect("simulation runs"))
}

fn row(model: &str, m: Option<f64>, method: Method) -> Row {
    rig_row(2, data_40db(), model, m, method, Some(40.0)).expect("identification runs")
}

fn rel(got: Option<f64>, want: f64) -> f64 {
    (got.expect("value present") / want - 1.0).abs()
}

#[test]
fn coulomb_model_recovers_k_c_fd_within_2_percent_at_40_db() {
    let (k, c, fd) = RIG_TRUTH;
    for method in [Method::FdMulti, Method::Fd] {
        let r = row("coulomb", None, method);
        assert!(rel(r.k, k) < 0.02, "{method:?} k {:?}", r.k);
        assert!(rel(r.c, c) < 0.02, "{method:?} c {:?}", r.c);
        assert!(rel(r.fd, fd) < 0.02, "{method:?} fd {:?}", r.fd);
        // The true structure predicts the held-out band-random records to near the noise floor.
        assert!(
            r.nmse1.unwrap() < 0.5 && r.nmse2.unwrap() < 0.5,
            "{:?} {:?}",
            r.nmse1,
            r.nmse2
        );
    }
}

#[test]
fn linear_model_absorbs_friction_into_damping_and_predicts_worse() {
    let lin = row("linear", None, Method::Fd);
    let cou = row("coulomb", None, Method::Fd);
    // As in Table 2: c well above the true 184 N s/m, k close to the truth.
    assert!(lin.c.unwrap() > 1.4 * RIG_TRUTH.1, "linear c {:?}", lin.c);
    assert!(rel(lin.k, RIG_TRUTH.0) < 0.05, "linear k {:?}", lin.k);
    assert!(
        lin.nmse1.unwrap() > 5.0 * cou.nmse1.unwrap(),
        "NMSE1 linear {:?} coulomb {:?}",
        lin.nmse1,
        cou.nmse1
    );
    assert!(
        lin.nmse2.unwrap() > 5.0 * cou.nmse2.unwrap(),
        "NMSE2 linear {:?} coulomb {:?}",
        lin.nmse2,
        cou.nmse2
    );
    // r values: friction carries a real share of the transmitted force.
    let r_fd = cou.r.unwrap().iter().find(|(n, _)| n == "fd").unwrap().1;
    assert!((8.0..30.0).contains(&r_fd), "r_fd {r_fd}");
}

#[test]
fn atan_model_behaves_as_table_3() {
    // Small M smears friction into a steep viscous term: c drops, F_d rises (Table 3);
    // M from 500 up approaches the sgn model.
    let m50 = row("coulomb-atan", Some(50.0), Method::Fd);
    let m1000 = row("coulomb-atan", Some(1000.0), Method::Fd);
    assert!(
        m50.c.unwrap() < 0.85 * m1000.c.unwrap(),
        "c {:?} vs {:?}",
        m50.c,
        m1000.c
    );
    assert!(
        m50.fd.unwrap() > 1.3 * m1000.fd.unwrap(),
        "fd {:?} vs {:?}",
        m50.fd,
        m1000.fd
    );
    assert!(
        rel(m1000.fd, RIG_TRUTH.2) < 0.06,
        "M=1000 fd {:?}",
        m1000.fd
    );
    assert!(rel(m1000.c, RIG_TRUTH.1) < 0.03, "M=1000 c {:?}", m1000.c);
}

#[test]
fn time_domain_fsm_is_clearly_worse_on_fd_than_frequency_domain() {
    let td = row(
        "coulomb",
        None,
        Method::Td {
            points_per_step: Some(20),
        },
    );
    let fd = row("coulomb", None, Method::Fd);
    let e_td = rel(td.fd, RIG_TRUTH.2);
    let e_fd = rel(fd.fd, RIG_TRUTH.2);
    assert!(
        e_td > 3.0 * e_fd && e_td > 0.03,
        "F_d error: TD {e_td:.4}, FD {e_fd:.4}"
    );
}
