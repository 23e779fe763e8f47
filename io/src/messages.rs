//! Warnings as a person reads them: one line per kind, not one per step or per sample. Warnings
//! of one kind differ only in their numbers ("step 3: no settled part ...", "step 4: no
//! settled part ..."); they are printed once, with how many there were and which steps.

/// A warning with its numbers masked: the kind it is of.
fn kind_of(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut in_number = false;
    for c in message.chars() {
        let digit = c.is_ascii_digit() || (in_number && matches!(c, '.' | 'e' | 'E' | '-' | '+'));
        if digit {
            if !in_number {
                out.push('#');
            }
            in_number = true;
        } else {
            in_number = false;
            out.push(c);
        }
    }
    out
}

/// The step a warning is about, when it starts with `step N`.
fn step_of(message: &str) -> Option<&str> {
    let rest = message.strip_prefix("step ")?;
    let end = rest
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(rest.len());
    (end > 0).then(|| &rest[..end])
}

/// `warnings` grouped by kind, in the order each kind first appears: a kind seen once is its
/// message; a kind seen more often is its first message with the count and the steps.
pub fn grouped(warnings: &[String]) -> Vec<String> {
    let mut kinds: Vec<(String, Vec<&String>)> = Vec::new();
    for w in warnings {
        let k = kind_of(w);
        match kinds.iter_mut().find(|(kind, _)| *kind == k) {
            Some((_, all)) => all.push(w),
            None => kinds.push((k, vec![w])),
        }
    }
    kinds
        .into_iter()
        .map(|(_, all)| {
            let first = all[0];
            if all.len() == 1 {
                return first.clone();
            }
            let steps: Vec<&str> = all.iter().filter_map(|w| step_of(w)).collect();
            // Messages that are the same but for their step: one line naming the steps.
            let same_but_step = steps.len() == all.len()
                && all.iter().all(|w| {
                    w[5 + step_of(w).map_or(0, str::len)..] == first[5 + steps[0].len()..]
                });
            if same_but_step {
                format!("steps {}{}", steps.join(", "), &first[5 + steps[0].len()..])
            } else if steps.len() == all.len() {
                format!(
                    "{first} (and {} more of this kind: steps {})",
                    all.len() - 1,
                    steps[1..].join(", ")
                )
            } else {
                format!("{first} (and {} more of this kind)", all.len() - 1)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strings(v: &[&str]) -> Vec<String> {
        v.iter().map(ToString::to_string).collect()
    }

    #[test]
    fn the_same_warning_for_several_steps_is_one_line() {
        let w = strings(&[
            "step 1: no settled part of 2 periods found; phasors from the last periods anyway",
            "step 2: no settled part of 2 periods found; phasors from the last periods anyway",
            "step 12: no settled part of 2 periods found; phasors from the last periods anyway",
        ]);
        assert_eq!(
            grouped(&w),
            [
                "steps 1, 2, 12: no settled part of 2 periods found; phasors from the last periods anyway"
            ]
        );
    }

    #[test]
    fn a_kind_with_other_numbers_is_counted_with_its_first() {
        let w = strings(&[
            "step 1 is labelled 0.5 Hz, but x is at 0.50860 Hz (standard deviation 1.0e-6 Hz)",
            "a different warning",
            "step 3 is labelled 0.1 Hz, but x is at 0.10170 Hz (standard deviation 8.0e-8 Hz)",
            "step 4 is labelled 5 Hz, but x is at 5.0950 Hz (standard deviation 2.0e-5 Hz)",
        ]);
        assert_eq!(
            grouped(&w),
            [
                "step 1 is labelled 0.5 Hz, but x is at 0.50860 Hz (standard deviation 1.0e-6 Hz) (and 2 more of this kind: steps 3, 4)",
                "a different warning",
            ]
        );
        let once = strings(&["relative_displacement_m changes at 3.2 s"]);
        assert_eq!(grouped(&once), once);
    }
}
