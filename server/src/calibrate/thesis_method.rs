//! The calibration method of the thesis echogym grew from (the "seed" report, chapters
//! 3.4/4.2), for comparison: per site, regress `F/r` on `v/r` (r: penetration depth, v:
//! penetration velocity) over the in-contact samples; the slope is the damping `b`, the
//! intercept the stiffness `k` of a linear mass-spring-damper, and `k/b` the ratio the
//! thesis tuned MuJoCo with.

use serde::Serialize;

use super::features::Series;

/// One site's regression.
#[derive(Debug, Clone, Serialize)]
pub struct ThesisFit {
    /// Site.
    pub site: String,
    /// Slope (≈ damping) [N·s/m].
    pub slope: f64,
    /// Intercept (≈ stiffness) [N/m].
    pub intercept: f64,
    /// Coefficient of determination.
    pub r2: f64,
    /// `intercept / slope` [1/s].
    pub k_over_b: f64,
    /// Samples used.
    pub samples: usize,
    /// Points for the plot (decimated): `(v/r, F/r)`.
    #[serde(skip)]
    pub points: Vec<(f64, f64)>,
}

/// The regression per site, with depth measured from the nominal surface (as the thesis
/// did: it knew no offset) and samples deeper than 2 mm.
pub fn thesis_method(series: &[Series], nominal_offset: f64) -> Vec<ThesisFit> {
    let mut sites: Vec<String> = series.iter().map(|s| s.site.clone()).collect();
    sites.sort();
    sites.dedup();
    sites
        .into_iter()
        .filter_map(|site| {
            let mut x = Vec::new();
            let mut y = Vec::new();
            for s in series.iter().filter(|s| s.site == site) {
                for i in 0..s.len() {
                    let r = s.depth[i] + nominal_offset;
                    if r > 0.002 && s.measured[i] > 0.0 {
                        x.push(-s.vz[i] / r);
                        y.push(s.measured[i] / r);
                    }
                }
            }
            let n = x.len();
            if n < 10 {
                return None;
            }
            let mx = x.iter().sum::<f64>() / n as f64;
            let my = y.iter().sum::<f64>() / n as f64;
            let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
            let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
            let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
            let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
            let intercept = my - slope * mx;
            let r2 = if sxx > 0.0 && syy > 0.0 {
                sxy * sxy / (sxx * syy)
            } else {
                0.0
            };
            let step = (n / 2000).max(1);
            Some(ThesisFit {
                site,
                slope,
                intercept,
                r2,
                k_over_b: if slope.abs() > 1e-12 {
                    intercept / slope
                } else {
                    f64::NAN
                },
                samples: n,
                points: x
                    .iter()
                    .zip(&y)
                    .step_by(step)
                    .map(|(a, b)| (*a, *b))
                    .collect(),
            })
        })
        .collect()
}
