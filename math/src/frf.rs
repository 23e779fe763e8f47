//! Frequency response functions of linear substructures (eqs. 10, 21-22).

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// A linear substructure M x'' + C x' + K x = f, with the nonlinear element attached at
/// degree of freedom `drive_dof`, where the excitation force also acts.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSubstructure {
    pub mass_kg: DMatrix<f64>,
    pub damping_n_s_per_m: DMatrix<f64>,
    pub stiffness_n_per_m: DMatrix<f64>,
    pub drive_dof: usize,
}

impl LinearSubstructure {
    /// One mass on a spring and a damper to ground (eq. 10).
    pub fn single_dof(mass_kg: f64, damping_n_s_per_m: f64, stiffness_n_per_m: f64) -> Self {
        LinearSubstructure {
            mass_kg: DMatrix::from_element(1, 1, mass_kg),
            damping_n_s_per_m: DMatrix::from_element(1, 1, damping_n_s_per_m),
            stiffness_n_per_m: DMatrix::from_element(1, 1, stiffness_n_per_m),
            drive_dof: 0,
        }
    }

    /// A chain ground -(k[0], c[0])- m[0] -(k[1], c[1])- m[1] - ... ; the element and the
    /// force act at `drive_dof`.
    pub fn chain(
        masses_kg: &[f64],
        springs_n_per_m: &[f64],
        dampers_n_s_per_m: &[f64],
        drive_dof: usize,
    ) -> Self {
        let n = masses_kg.len();
        assert!(springs_n_per_m.len() == n && dampers_n_s_per_m.len() == n && drive_dof < n);
        let band = |v: &[f64]| {
            let mut m = DMatrix::zeros(n, n);
            for i in 0..n {
                m[(i, i)] += v[i];
                if i > 0 {
                    m[(i - 1, i - 1)] += v[i];
                    m[(i - 1, i)] -= v[i];
                    m[(i, i - 1)] -= v[i];
                }
            }
            m
        };
        LinearSubstructure {
            mass_kg: DMatrix::from_diagonal(&DVector::from_column_slice(masses_kg)),
            damping_n_s_per_m: band(dampers_n_s_per_m),
            stiffness_n_per_m: band(springs_n_per_m),
            drive_dof,
        }
    }

    /// Substructure I of the paper's 3-DOF example: ground -(k11, c11)- m1 -(k12, c12)- m2,
    /// driven at m2 where the element attaches.
    pub fn paper_three_dof_substructure_i() -> Self {
        Self::chain(&[3.0, 2.0], &[6000.0, 6000.0], &[6.0, 6.0], 1)
    }

    /// Receptance alpha_dd(w) at the drive point [m/N], w in rad/s.
    pub fn drive_point_receptance(&self, omega_rad_s: f64) -> Complex64 {
        let n = self.mass_kg.nrows();
        let z = DMatrix::from_fn(n, n, |i, j| {
            Complex64::new(
                self.stiffness_n_per_m[(i, j)] - omega_rad_s * omega_rad_s * self.mass_kg[(i, j)],
                omega_rad_s * self.damping_n_s_per_m[(i, j)],
            )
        });
        let mut e = DVector::zeros(n);
        e[self.drive_dof] = Complex64::new(1.0, 0.0);
        let col = z
            .lu()
            .solve(&e)
            .expect("dynamic stiffness of a damped structure is invertible");
        col[self.drive_dof]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_dof_receptance_is_eq_10() {
        let s = LinearSubstructure::single_dof(2.0, 3.0, 5000.0);
        for w in [0.0, 10.0, 50.0, 200.0] {
            let expect = Complex64::new(1.0, 0.0) / Complex64::new(5000.0 - w * w * 2.0, w * 3.0);
            assert!(
                (s.drive_point_receptance(w) - expect).norm() < 1e-15 * expect.norm().max(1e-9)
            );
        }
    }

    #[test]
    fn two_dof_drive_point_matches_closed_form_inverse() {
        // Z = [[z11, z12], [z12, z22]]; alpha_22 = z11 / (z11 z22 - z12^2).
        let s = LinearSubstructure::paper_three_dof_substructure_i();
        for w in [1.0, 31.4, 44.7, 80.0, 500.0] {
            let j = Complex64::new(0.0, 1.0);
            let z11 = 12000.0 - w * w * 3.0 + j * w * 12.0;
            let z22 = 6000.0 - w * w * 2.0 + j * w * 6.0;
            let z12 = -6000.0 - j * w * 6.0;
            let expect = z11 / (z11 * z22 - z12 * z12);
            let got = s.drive_point_receptance(w);
            assert!(
                (got - expect).norm() < 1e-12 * expect.norm(),
                "w {w}: {got} vs {expect}"
            );
        }
    }
}
