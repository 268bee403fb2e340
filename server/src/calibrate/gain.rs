//! How much a change of the model explains: the relative drop of an RMSE, and the share
//! of its excess over the noise floor.

/// How much lower `after` is than `before`, relative to `before`.
pub fn relative_drop(before: f64, after: f64) -> f64 {
    (before - after) / before.max(1e-12)
}

/// Share of the excess of an RMSE `before` over the noise floor `noise` that going to
/// `after` explains; 0 where there is no excess (free air is often at the floor).
pub fn explained_share(before: f64, after: f64, noise: f64) -> f64 {
    let excess = before * before - noise * noise;
    if excess <= 1e-12 {
        return 0.0;
    }
    (before * before - after * after) / excess
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_share_is_of_the_excess_over_the_noise_floor() {
        assert!((relative_drop(2.0, 1.5) - 0.25).abs() < 1e-12);
        // 2² − 1² = 3 of excess; going to √2 explains 4 − 2 = 2 of it.
        assert!((explained_share(2.0, 2f64.sqrt(), 1.0) - 2.0 / 3.0).abs() < 1e-12);
        // At the floor there is nothing to explain.
        assert_eq!(explained_share(1.0, 0.9, 1.0), 0.0);
    }
}
