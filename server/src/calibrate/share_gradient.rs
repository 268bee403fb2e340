//! How a site's tangential share changes over the torso's top: the gradient
//! [`super::lateral_share`] fits where three sites or more have shares of their own, and
//! the replay adds at the probe's position. Apart from both so that the replay, which
//! the features read, does not import the share's fit (which reads the features).

/// How the share changes over the torso's top: `per_m · (xy − at)` is added to a
/// site's share for a probe at `xy`, `at` where that site's share was read.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShareGradient {
    /// `∂share/∂(x, y)` [1/m]: rows the share's x and y, columns the position's.
    pub per_m: [[f64; 2]; 2],
    /// Site → the mean xy of the samples its share was read on (normal force²-weighted).
    pub at: Vec<(String, [f64; 2])>,
}

impl ShareGradient {
    /// What the gradient adds to `site`'s share at `xy` (nothing at an unknown site).
    pub fn add(&self, site: &str, xy: [f64; 2]) -> [f64; 2] {
        let Some((_, at)) = self.at.iter().find(|(s, _)| s == site) else {
            return [0.0; 2];
        };
        let d = [xy[0] - at[0], xy[1] - at[1]];
        [0, 1].map(|r| self.per_m[r][0] * d[0] + self.per_m[r][1] * d[1])
    }
}
