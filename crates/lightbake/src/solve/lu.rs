//! Dense LU with partial pivoting (f64) of I − diag(ρ_c)·F, one factorisation per colour
//! channel: the reference every iterative solver is tested against. O(n³) time and O(n²)
//! memory, so it is limited to [`super::DIRECT_MAX_NODES`] nodes.

use glam::Vec3;

use super::{Recorder, Solution, System};

/// Solves A·x = b in place by LU with partial pivoting; `a` is row-major n×n.
/// Returns false for a singular matrix.
pub fn lu_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for k in 0..n {
        // Pivot.
        let (mut p, mut best) = (k, a[k * n + k].abs());
        for i in k + 1..n {
            let v = a[i * n + k].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            b.swap(k, p);
        }
        let pivot = a[k * n + k];
        for i in k + 1..n {
            let f = a[i * n + k] / pivot;
            if f == 0.0 {
                continue;
            }
            a[i * n + k] = f;
            let (top, bottom) = a.split_at_mut(i * n);
            let row_k = &top[k * n..k * n + n];
            let row_i = &mut bottom[..n];
            for j in k + 1..n {
                row_i[j] -= f * row_k[j];
            }
            b[i] -= f * b[k];
        }
    }
    for k in (0..n).rev() {
        let mut s = b[k];
        for j in k + 1..n {
            s -= a[k * n + j] * b[j];
        }
        b[k] = s / a[k * n + k];
    }
    true
}

/// Solves `system` exactly (to rounding).
///
/// # Panics
/// If the system has more than [`super::DIRECT_MAX_NODES`] nodes (callers check first).
pub fn solve(system: &System<'_>) -> Solution {
    let n = system.len();
    assert!(
        n <= super::DIRECT_MAX_NODES,
        "dense LU limited to {} nodes",
        super::DIRECT_MAX_NODES
    );
    let mut rec = Recorder::new(system.progress);
    let mut b = vec![Vec3::ZERO; n];
    let mut ok = true;
    for c in 0..3 {
        let mut a = vec![0.0f64; n * n];
        for i in 0..n {
            a[i * n + i] = 1.0;
            let rho = system.albedo[i][c] as f64;
            let (cols, vals) = system.transport.row(i);
            for (&j, &w) in cols.iter().zip(vals) {
                a[i * n + j as usize] -= rho * w as f64;
            }
        }
        let mut rhs: Vec<f64> = system.source.iter().map(|s| s[c] as f64).collect();
        ok &= lu_solve(&mut a, &mut rhs, n);
        for i in 0..n {
            b[i][c] = rhs[i] as f32;
        }
    }
    let residual = system.relative_residual(&super::to_f64(&b));
    rec.record(1.0, residual, Some(0.0));
    Solution {
        solver: "direct",
        b,
        indirect: Vec::new(),
        history: rec.history,
        converged: ok,
        iterations: 1.0,
        rays: 0,
        stop_reason: if ok {
            format!("dense LU of {n} unknowns per channel, relative residual {residual:.2e}")
        } else {
            "the matrix is singular".to_string()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lu_solves_a_known_system() {
        // [[2, 1, 1], [4, -6, 0], [-2, 7, 2]] x = [5, -2, 9] → x = [1, 1, 2]
        let mut a = vec![2.0, 1.0, 1.0, 4.0, -6.0, 0.0, -2.0, 7.0, 2.0];
        let mut b = vec![5.0, -2.0, 9.0];
        assert!(lu_solve(&mut a, &mut b, 3));
        for (x, e) in b.iter().zip([1.0, 1.0, 2.0]) {
            assert!((x - e).abs() < 1e-12);
        }
        let mut singular = vec![1.0, 2.0, 2.0, 4.0];
        assert!(!lu_solve(&mut singular, &mut [1.0, 2.0], 2));
    }
}
