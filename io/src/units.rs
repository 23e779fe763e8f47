//! Units as measurement files write them, and their conversion to the SI unit of a forcemap
//! channel: one table, used by every reader that meets a unit (a CSV units row, a unit in a
//! column's name, an MDF4 channel's unit, a TDMS `unit_string`, a channel map's `unit`).

/// What a channel measures, which decides the SI unit its values must end in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    Time,
    Length,
    Velocity,
    Acceleration,
    Force,
    Frequency,
    /// A count without unit (a step index, a sample counter).
    Count,
}

impl Quantity {
    /// The SI unit forcemap works in.
    pub fn si_unit(self) -> &'static str {
        match self {
            Quantity::Time => "s",
            Quantity::Length => "m",
            Quantity::Velocity => "m/s",
            Quantity::Acceleration => "m/s^2",
            Quantity::Force => "N",
            Quantity::Frequency => "Hz",
            Quantity::Count => "-",
        }
    }

    /// The quantity of a contract column by its name's SI suffix (`time_s`, `force_n`,
    /// `relative_displacement_m`, `mass_acceleration_mps2`, `frequency_hz`, `step`).
    pub fn of_column(name: &str) -> Option<Quantity> {
        Some(if name == "step" {
            Quantity::Count
        } else if name.ends_with("_mps2") {
            Quantity::Acceleration
        } else if name.ends_with("_mps") {
            Quantity::Velocity
        } else if name.ends_with("_hz") {
            Quantity::Frequency
        } else if name.ends_with("_s") {
            Quantity::Time
        } else if name.ends_with("_n") {
            Quantity::Force
        } else if name.ends_with("_m") {
            Quantity::Length
        } else {
            return None;
        })
    }
}

/// Standard gravity [m/s^2] (the `g` of an accelerometer's unit).
pub const STANDARD_GRAVITY_MPS2: f64 = 9.80665;
const INCH_M: f64 = 0.0254;
const POUND_FORCE_N: f64 = 4.448_221_615_260_5;

/// The known units: spellings, what they measure and their factor to SI.
const UNITS: &[(&[&str], Quantity, f64)] = &[
    (&["s", "sec"], Quantity::Time, 1.0),
    (&["ms"], Quantity::Time, 1e-3),
    (&["us", "µs", "μs"], Quantity::Time, 1e-6),
    (&["m"], Quantity::Length, 1.0),
    (&["cm"], Quantity::Length, 1e-2),
    (&["mm"], Quantity::Length, 1e-3),
    (&["um", "µm", "μm"], Quantity::Length, 1e-6),
    (&["in", "inch"], Quantity::Length, INCH_M),
    (&["m/s"], Quantity::Velocity, 1.0),
    (&["mm/s"], Quantity::Velocity, 1e-3),
    (&["in/s", "ips"], Quantity::Velocity, INCH_M),
    (
        &["m/s^2", "m/s²", "m/s2", "m/s/s"],
        Quantity::Acceleration,
        1.0,
    ),
    (&["mm/s^2", "mm/s²", "mm/s2"], Quantity::Acceleration, 1e-3),
    (
        &["g", "gn", "g0"],
        Quantity::Acceleration,
        STANDARD_GRAVITY_MPS2,
    ),
    (&["n"], Quantity::Force, 1.0),
    (&["kn"], Quantity::Force, 1e3),
    (&["lbf"], Quantity::Force, POUND_FORCE_N),
    // The kip (kilo-pound-force) of US structural labs.
    (
        &["kip", "kipf", "klbf"],
        Quantity::Force,
        1e3 * POUND_FORCE_N,
    ),
    (&["hz", "1/s"], Quantity::Frequency, 1.0),
    (&["", "-", "1"], Quantity::Count, 1.0),
];

/// A unit read from a file, understood.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    pub quantity: Quantity,
    /// Multiply a value in this unit by it for SI.
    pub to_si: f64,
}

/// The unit a text names (`mm`, `[mm]`, `(kN)`, `m/s²`, `m s^-2`), or `None` when it is not
/// one of the known units. Case matters only where it must (`m` and `M` are not confused:
/// only lengths and accelerations are matched in lower case as written, forces and
/// frequencies in any case).
pub fn parse_unit(text: &str) -> Option<Unit> {
    let bare = text
        .trim()
        .trim_start_matches(['[', '('])
        .trim_end_matches([']', ')'])
        .trim();
    let normal = bare
        .replace(' ', "")
        .replace("*s^-2", "/s^2")
        .replace("s^-2", "/s^2");
    let normal = normal.replace("//", "/");
    for (spellings, quantity, to_si) in UNITS {
        let matches = match quantity {
            // N, kN, lbf, Hz: case-insensitive (`n`, `KN` and `HZ` are unambiguous here).
            Quantity::Force | Quantity::Frequency => {
                spellings.iter().any(|s| s.eq_ignore_ascii_case(&normal))
            }
            _ => spellings.contains(&normal.as_str()),
        };
        if matches {
            return Some(Unit {
                quantity: *quantity,
                to_si: *to_si,
            });
        }
    }
    None
}

/// The unit a column's name carries at its end, in brackets or parentheses:
/// `Force (N)` -> ("Force", "N"), `Displacement [mm]` -> ("Displacement", "mm").
pub fn unit_in_name(name: &str) -> Option<(&str, &str)> {
    let name = name.trim_end();
    let (open, close) = match name.chars().last()? {
        ')' => ('(', ')'),
        ']' => ('[', ']'),
        _ => return None,
    };
    let start = name.rfind(open)?;
    let unit = &name[start + 1..name.len() - close.len_utf8()];
    Some((name[..start].trim_end(), unit.trim()))
}

/// How a value reaches forcemap's unit, for the notice that names each conversion:
/// "mm -> m (x 0.001)".
pub fn describe_conversion(unit: &str, quantity: Quantity, factor: f64) -> String {
    format!("{unit} -> {} (x {factor})", quantity.si_unit())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_units_convert_to_si() {
        let f = |t: &str| parse_unit(t).map(|u| (u.quantity, u.to_si));
        assert_eq!(f("mm"), Some((Quantity::Length, 1e-3)));
        assert_eq!(f("[mm]"), Some((Quantity::Length, 1e-3)));
        assert_eq!(f("(kN)"), Some((Quantity::Force, 1e3)));
        assert_eq!(f("kN"), f("KN"));
        assert_eq!(f("lbf").unwrap().1, 4.4482216152605);
        assert_eq!(f("in").unwrap().1, 0.0254);
        assert!((f("kip").unwrap().1 - 4_448.221_615_260_5).abs() < 1e-9);
        assert_eq!(f("in/s"), Some((Quantity::Velocity, 0.0254)));
        assert_eq!(f("g"), Some((Quantity::Acceleration, 9.80665)));
        assert_eq!(f("m/s²"), Some((Quantity::Acceleration, 1.0)));
        assert_eq!(f("m s^-2"), Some((Quantity::Acceleration, 1.0)));
        assert_eq!(f("mm/s^2"), Some((Quantity::Acceleration, 1e-3)));
        assert_eq!(f("ms"), Some((Quantity::Time, 1e-3)));
        assert_eq!(f("Hz"), Some((Quantity::Frequency, 1.0)));
        assert_eq!(f("um"), Some((Quantity::Length, 1e-6)));
        assert_eq!(f("µm"), f("um"));
    }

    #[test]
    fn unknown_units_and_wrong_case_are_not_guessed() {
        assert_eq!(parse_unit("V"), None);
        assert_eq!(parse_unit("degC"), None);
        // MM is not a millimetre (nor a megametre): refused rather than guessed.
        assert_eq!(parse_unit("MM"), None);
        assert_eq!(parse_unit("G"), None);
    }

    #[test]
    fn a_unit_is_found_at_the_end_of_a_name() {
        assert_eq!(unit_in_name("Force (N)"), Some(("Force", "N")));
        assert_eq!(
            unit_in_name("Displacement [mm]"),
            Some(("Displacement", "mm"))
        );
        assert_eq!(unit_in_name("Body_AccZ[g]"), Some(("Body_AccZ", "g")));
        assert_eq!(unit_in_name("Force"), None);
        assert_eq!(unit_in_name("Volt(1)"), Some(("Volt", "1")));
    }

    #[test]
    fn contract_columns_have_their_quantity() {
        assert_eq!(Quantity::of_column("force_n"), Some(Quantity::Force));
        assert_eq!(Quantity::of_column("time_s"), Some(Quantity::Time));
        assert_eq!(
            Quantity::of_column("mass_acceleration_mps2"),
            Some(Quantity::Acceleration)
        );
        assert_eq!(
            Quantity::of_column("relative_displacement_m"),
            Some(Quantity::Length)
        );
        assert_eq!(
            Quantity::of_column("frequency_hz"),
            Some(Quantity::Frequency)
        );
        assert_eq!(Quantity::of_column("step"), Some(Quantity::Count));
    }
}
