//! The reference numbers of W.-J. Kim (1997), Tables 1-4, as METHOD.md restates them, and the
//! truths forcemap simulates against.

/// One row of a paper table. `None` where the column does not apply (or is garbled in the
/// source).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    pub table: u8,
    /// "I" or "II" for Table 1, None for the rig.
    pub case: Option<&'static str>,
    pub model: &'static str,
    /// atan slope M where the model is an atan one.
    pub atan_m: Option<f64>,
    pub k: f64,
    pub c: f64,
    pub fd: Option<f64>,
    pub s: Option<f64>,
    pub nmse1: Option<f64>,
    pub nmse2: Option<f64>,
}

const fn row(
    table: u8,
    case: Option<&'static str>,
    model: &'static str,
    atan_m: Option<f64>,
    kcfs: (f64, f64, Option<f64>, Option<f64>),
    nmse: (Option<f64>, Option<f64>),
) -> PaperRow {
    PaperRow {
        table,
        case,
        model,
        atan_m,
        k: kcfs.0,
        c: kcfs.1,
        fd: kcfs.2,
        s: kcfs.3,
        nmse1: nmse.0,
        nmse2: nmse.1,
    }
}

/// Table 1: 3-DOF example, identified element parameters (S in N/m^3).
pub const TABLE1: [PaperRow; 6] = [
    row(
        1,
        Some("I"),
        "coulomb-cubic",
        None,
        (7540.8, 37.5, Some(4.0), Some(4.54e8)),
        (None, None),
    ),
    row(
        1,
        Some("I"),
        "coulomb-atan-cubic",
        Some(1e5),
        (7542.8, 37.0, Some(4.0), Some(4.54e8)),
        (None, None),
    ),
    row(
        1,
        Some("I"),
        "coulomb-atan-cubic",
        Some(1e3),
        (7731.8, 12.1, Some(5.7), Some(3.12e8)),
        (None, None),
    ),
    row(
        1,
        Some("II"),
        "coulomb-cubic",
        None,
        (7731.8, 19.6, Some(5.0), Some(3.12e8)),
        (None, None),
    ),
    row(
        1,
        Some("II"),
        "coulomb-atan-cubic",
        Some(1e5),
        (7745.4, 19.8, Some(5.0), Some(3.11e8)),
        (None, None),
    ),
    row(
        1,
        Some("II"),
        "coulomb-atan-cubic",
        Some(1e3),
        (7979.3, 18.3, Some(5.3), None),
        (None, None),
    ),
];

/// Table 1 truth: k, c, F_d, S of eq. 18.
pub const TABLE1_TRUTH: (f64, f64, f64, f64) = (8000.0, 20.0, 5.0, 3.0e8);

/// Table 2: the rig, FD method.
pub const TABLE2: [PaperRow; 2] = [
    row(
        2,
        None,
        "linear",
        None,
        (6259.1, 392.0, None, None),
        (Some(11.0), Some(17.2)),
    ),
    row(
        2,
        None,
        "coulomb",
        None,
        (6378.2, 184.6, Some(12.3), None),
        (Some(4.0), Some(6.5)),
    ),
];

/// The paper's r values for Table 2 (percent of the RMS transmitted force).
pub const TABLE2_R: [(&str, &[(&str, f64)]); 2] = [
    ("linear", &[("k", 49.4), ("c", 50.6)]),
    ("coulomb", &[("k", 58.0), ("c", 27.4), ("fd", 14.5)]),
];

/// Table 3: the rig, atan model for several M.
pub const TABLE3: [PaperRow; 5] = [
    row(
        3,
        None,
        "coulomb-atan",
        Some(50.0),
        (6360.4, 116.6, Some(21.4), None),
        (Some(6.7), Some(6.9)),
    ),
    row(
        3,
        None,
        "coulomb-atan",
        Some(100.0),
        (6371.4, 155.5, Some(16.1), None),
        (Some(4.5), Some(6.2)),
    ),
    row(
        3,
        None,
        "coulomb-atan",
        Some(500.0),
        (6383.1, 180.2, Some(12.9), None),
        (Some(3.6), Some(6.0)),
    ),
    row(
        3,
        None,
        "coulomb-atan",
        Some(1000.0),
        (6384.1, 182.7, Some(12.5), None),
        (Some(3.7), Some(6.0)),
    ),
    row(
        3,
        None,
        "coulomb-atan",
        Some(1e4),
        (6381.8, 184.6, Some(12.3), None),
        (Some(3.9), Some(6.5)),
    ),
];

/// Table 4: the rig, time-domain FSM with 20 points per frequency.
pub const TABLE4: [PaperRow; 1] = [row(
    4,
    None,
    "coulomb",
    None,
    (6790.6, 188.5, Some(4.1), None),
    (Some(8.7), Some(8.1)),
)];

/// The simulated stand-in for the paper's physical rig: its identified Coulomb values as the
/// truth (m 36 kg, k 6380 N/m, c 184 N s/m, F_d 12.3 N).
pub const RIG_TRUTH: (f64, f64, f64) = (6380.0, 184.0, 12.3);
