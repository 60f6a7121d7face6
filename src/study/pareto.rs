//! The Pareto frontier of (time, error): the settings no other setting beats on both.
//!
//! Decision: measurements have a resolution, so "beats" means beyond it: [`frontier_within`]
//! counts a time difference below `time_tolerance` (relative) and an error difference below
//! `error_tolerance` (relative) as a tie. Without that, two settings with the same error would
//! dominate each other by the noise of a timer.

/// Indices of the points on the frontier of `points` = (time, error), both to be minimized. A
/// point is dominated when another is no worse in both and strictly better in one. Sorted by
/// time.
pub fn frontier(points: &[(f64, f64)]) -> Vec<usize> {
    let mut on: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let (t, e) = points[i];
            t.is_finite()
                && e.is_finite()
                && !points
                    .iter()
                    .enumerate()
                    .any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e))
        })
        .collect();
    on.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    on
}

/// The frontier with measurement tolerances: j dominates i when j is no worse in both beyond the
/// tolerances and better in one by more than its tolerance.
pub fn frontier_within(
    points: &[(f64, f64)],
    time_tolerance: f64,
    error_tolerance: f64,
) -> Vec<usize> {
    let better = |a: f64, b: f64, tol: f64| a < b * (1.0 - tol);
    let no_worse = |a: f64, b: f64, tol: f64| a <= b * (1.0 + tol);
    let mut on: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let (t, e) = points[i];
            t.is_finite()
                && e.is_finite()
                && !points.iter().enumerate().any(|(j, &(tj, ej))| {
                    j != i
                        && tj.is_finite()
                        && ej.is_finite()
                        && no_worse(tj, t, time_tolerance)
                        && no_worse(ej, e, error_tolerance)
                        && (better(tj, t, time_tolerance) || better(ej, e, error_tolerance))
                })
        })
        .collect();
    on.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    on
}

/// [`frontier_within`] for measured points = (time, relative time spread, error): two times tie
/// when they differ by less than `time_tolerance` or by less than their spreads together, so a
/// noisier measurement needs a larger difference to count.
pub fn frontier_with_spread(
    points: &[(f64, f64, f64)],
    time_tolerance: f64,
    error_tolerance: f64,
) -> Vec<usize> {
    let finite = |&(t, s, e): &(f64, f64, f64)| t.is_finite() && e.is_finite() && s.is_finite();
    let tolerance = |si: f64, sj: f64| time_tolerance.max(si + sj);
    let mut on: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let (t, s, e) = points[i];
            finite(&points[i])
                && !points.iter().enumerate().any(|(j, pj)| {
                    let (tj, sj, ej) = *pj;
                    let tol = tolerance(s, sj);
                    j != i
                        && finite(pj)
                        && tj <= t * (1.0 + tol)
                        && ej <= e * (1.0 + error_tolerance)
                        && (tj < t * (1.0 - tol) || ej < e * (1.0 - error_tolerance))
                })
        })
        .collect();
    on.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    on
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dominated_points_are_left_out() {
        let pts = [(1.0, 5.0), (2.0, 3.0), (3.0, 3.5), (4.0, 1.0), (2.5, 3.0)];
        assert_eq!(frontier(&pts), vec![0, 1, 3]);
    }

    #[test]
    fn differences_within_the_tolerances_are_ties() {
        // 3 % faster with the same error: a tie at 5 % time tolerance, so both stay.
        let pts = [(1.0, 0.010), (0.97, 0.010), (0.5, 0.02)];
        assert_eq!(frontier_within(&pts, 0.05, 0.01), vec![2, 1, 0]);
        // 30 % faster with the same error dominates.
        let pts = [(1.0, 0.010), (0.7, 0.010)];
        assert_eq!(frontier_within(&pts, 0.05, 0.01), vec![1]);
        // Zero tolerances are the plain frontier.
        let pts = [(1.0, 5.0), (2.0, 3.0), (3.0, 3.5), (4.0, 1.0), (2.5, 3.0)];
        assert_eq!(frontier_within(&pts, 0.0, 0.0), frontier(&pts));
    }

    #[test]
    fn equal_points_both_stay_and_nan_is_never_on_it() {
        let pts = [(1.0, 1.0), (1.0, 1.0), (f64::NAN, 0.0)];
        assert_eq!(frontier(&pts), vec![0, 1]);
    }

    #[test]
    fn noisy_times_need_larger_differences() {
        // 8 % faster at equal error: dominates when both times are exact to 1 %...
        let pts = [(1.0, 0.01, 0.010), (0.92, 0.01, 0.010)];
        assert_eq!(frontier_with_spread(&pts, 0.05, 0.01), vec![1]);
        // ...but is a tie when each time spreads by 5 %.
        let pts = [(1.0, 0.05, 0.010), (0.92, 0.05, 0.010)];
        assert_eq!(frontier_with_spread(&pts, 0.05, 0.01), vec![1, 0]);
        // Zero spreads are frontier_within.
        let pts = [
            (1.0, 0.0, 5.0),
            (2.0, 0.0, 3.0),
            (3.0, 0.0, 3.5),
            (4.0, 0.0, 1.0),
        ];
        let plain: Vec<(f64, f64)> = pts.iter().map(|p| (p.0, p.2)).collect();
        assert_eq!(
            frontier_with_spread(&pts, 0.05, 0.01),
            frontier_within(&plain, 0.05, 0.01)
        );
    }
}
