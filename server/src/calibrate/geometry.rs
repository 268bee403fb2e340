//! The body's surface: part of the **baseline**, never an effect.
//!
//! A real body is curved: the skin under one site stands a few millimetres higher or
//! lower than under another, and a slide follows the skin's slope and curvature along
//! its path. With one global surface height, `k × 3 mm ≈ 4 N` of per-site force offset
//! looks like per-site stiffness, and a slide over a curved belly looks like anything.
//! So:
//! - every **site** has its own height relative to the global surface (shared by all the
//!   recordings made there, so a press and a slide at one site agree);
//! - every **recording** has a height correction of its own — a probe placed again at a
//!   site lands a millimetre or two away, where a curved body stands a fraction of a
//!   millimetre higher or lower — and, when it moves sideways in contact (a slide), a
//!   slope and, when long enough, a curvature along its direction:
//!
//! ```text
//! z_surface(xy) = nominal + offset + h_site + h_rec + slope·s + ½·curvature·s²,
//! s = (xy − centre_rec) · along_rec   \[m\]
//! ```
//!
//! Heights are **measured** from the force's contact onset wherever a recording
//! approaches from free air ([`super::onset`]), not fitted: a fitted height trades against
//! per-site stiffness (a stiffer site and a higher skin both give more force at a given
//! probe height), which `site_heterogeneity` must name. A site's height is the median of
//! its recordings' onsets, a recording's correction its own onset's difference from it
//! (0 without an onset). Only a site where no recording has an onset gets its height
//! fitted. A path's slope and curvature are fitted, with a prior towards flat
//! ([`PATH_PRIOR`]: one prior standard deviation must pay for itself by lowering the
//! recording's residual by ≈ [`PRIOR_FORCE_N`] RMS); a held-out slide's path is fitted on
//! it (a nuisance state, listed in the report). A path's shape is its own (two slides at
//! one site may cross the skin in different directions). The replay keeps the particle
//! torso flat and shifts the probe instead (the same contact depth and depth rate), so
//! geometry costs nothing in the simulator.

use serde::{Deserialize, Serialize};

use crate::recordings::Dataset;

/// Sideways extent in contact \[m\] above which a path's slope is fitted.
pub const SLOPE_EXTENT: f64 = 0.02;
/// Sideways extent in contact \[m\] above which a path's curvature is fitted too.
pub const CURVATURE_EXTENT: f64 = 0.04;
/// Below the nominal surface by this much \[m\], a sample counts as in contact when the
/// geometry is laid out (before any fit).
const CONTACT_MARGIN: f64 = 0.002;
/// Prior standard deviations of a path's slope and curvature [1/m].
pub const PATH_PRIOR: [f64; 2] = [0.3, 10.0];
/// RMS force \[N\] over a recording that one prior standard deviation is worth.
pub const PRIOR_FORCE_N: f64 = 0.05;

/// Where a surface parameter came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Not fitted (0).
    #[default]
    Unfitted,
    /// Fitted on the training recordings.
    Training,
    /// Fitted on the held-out recordings that show it (no training recording does): a
    /// nuisance, like a breathing phase.
    Heldout,
    /// Measured from the force's contact onset (see [`super::onset`]), not fitted.
    Onset,
}

/// The surface height under one site.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SiteSurface {
    /// Site name.
    pub site: String,
    /// World xy of the site (the mean contact point of its recordings) \[m\].
    pub origin: [f64; 2],
    /// Height relative to the model's global surface \[m\].
    pub height_m: f64,
    /// Where the height came from.
    pub source: Source,
}

/// The surface along one recording's path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathSurface {
    /// Recording index.
    pub recording: usize,
    /// Mean contact point, world xy \[m\].
    pub centre: [f64; 2],
    /// Height correction of this recording relative to its site \[m\].
    pub height_m: f64,
    /// Where the height correction came from.
    #[serde(default)]
    pub height_source: Source,
    /// Where along the path `height_m` holds \[m from `centre`\]: the contact onset's
    /// point when the height came from it (a slide's onset is where it began, centimetres
    /// from its centre), else 0. Slope and curvature then bend the path about that
    /// point, and the skin at the onset stays where the onset put it.
    #[serde(default)]
    pub anchor_m: f64,
    /// The earlier segment of the same file whose path this one is (a logger's pause
    /// cut the file; the skin under it did not change): its slope, curvature and, where
    /// this segment has no onset of its own, its height hold here too.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follows: Option<usize>,
    /// Unit direction in world xy the probe moves along.
    pub along: [f64; 2],
    /// Extent of the contact points along `along` \[m\].
    pub extent_m: f64,
    /// Slope along `along` (dz/ds) at the site's origin.
    pub slope: f64,
    /// Curvature along `along` (d²z/ds²) [1/m]; negative: a dome. 0 for short paths.
    pub curvature_per_m: f64,
    /// Where slope and curvature came from.
    pub source: Source,
}

impl PathSurface {
    /// Whether the path moves sideways far enough for a slope.
    pub fn has_slope(&self) -> bool {
        self.extent_m > SLOPE_EXTENT
    }

    /// Whether the path is long enough for a curvature.
    pub fn has_curvature(&self) -> bool {
        self.extent_m > CURVATURE_EXTENT
    }
}

/// Surface height relative to the global surface at world `xy` for a recording made at
/// `site` along `path`, and its rate of change for a probe moving at `v` (world, m/s).
pub fn shift(
    site: Option<&SiteSurface>,
    path: Option<&PathSurface>,
    xy: [f64; 2],
    v: [f64; 3],
) -> (f64, f64) {
    let Some(site) = site else {
        return (0.0, 0.0);
    };
    let Some(path) = path else {
        return (site.height_m, 0.0);
    };
    let s = (xy[0] - path.centre[0]) * path.along[0] + (xy[1] - path.centre[1]) * path.along[1];
    let ds = v[0] * path.along[0] + v[1] * path.along[1];
    let a = path.anchor_m;
    let z = site.height_m
        + path.height_m
        + path.slope * (s - a)
        + 0.5 * path.curvature_per_m * (s * s - a * a);
    let dz = (path.slope + path.curvature_per_m * s) * ds;
    (z, dz)
}

/// Contact points (world xy) of recording `i`; all its points if it never went below
/// the nominal surface.
fn contact_points(dataset: &Dataset, i: usize) -> Vec<[f64; 2]> {
    let z_contact = dataset.meta.nominal_surface_z + CONTACT_MARGIN;
    let rec = &dataset.recordings[i];
    let points: Vec<[f64; 2]> = rec
        .p
        .iter()
        .filter(|p| p[2] < z_contact)
        .map(|p| [p[0], p[1]])
        .collect();
    if points.is_empty() {
        rec.p.iter().map(|p| [p[0], p[1]]).collect()
    } else {
        points
    }
}

fn mean(points: &[[f64; 2]]) -> [f64; 2] {
    let n = points.len().max(1) as f64;
    points
        .iter()
        .fold([0.0; 2], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n])
}

/// Every site's surface (flat, at the global height), at the mean contact point of the
/// recordings made there.
pub fn sites(dataset: &Dataset) -> Vec<SiteSurface> {
    let mut sites: Vec<(String, Vec<[f64; 2]>)> = Vec::new();
    for (i, entry) in dataset.meta.recordings.iter().enumerate() {
        let points = contact_points(dataset, i);
        match sites.iter_mut().find(|(s, _)| *s == entry.site) {
            Some((_, all)) => all.extend(points),
            None => sites.push((entry.site.clone(), points)),
        }
    }
    sites
        .into_iter()
        .map(|(site, points)| SiteSurface {
            site,
            origin: mean(&points),
            height_m: 0.0,
            source: Source::Unfitted,
        })
        .collect()
}

/// The points' mean, their principal axis (a unit direction in xy) and their extent
/// along it \[m\].
pub fn principal_axis(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2], f64) {
    let centre = mean(points);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - centre[0], p[1] - centre[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let along = [angle.cos(), angle.sin()];
    let (lo, hi) = points.iter().fold((0.0f64, 0.0f64), |(lo, hi), p| {
        let s = (p[0] - centre[0]) * along[0] + (p[1] - centre[1]) * along[1];
        (lo.min(s), hi.max(s))
    });
    (centre, along, hi - lo)
}

/// A path for every recording (direction: the principal axis of its contact points),
/// flat to begin with. The segments of one file share one path: its axis from all their
/// contact points, the later ones following the first (`follows`).
pub fn paths(dataset: &Dataset) -> Vec<PathSurface> {
    let file_of = |i: usize| {
        let entry = &dataset.meta.recordings[i];
        entry
            .segment
            .as_ref()
            .map_or(entry.file.as_str(), |s| s.source.as_str())
    };
    let n = dataset.recordings.len();
    (0..n)
        .map(|i| {
            let same_file: Vec<usize> = (0..n).filter(|&j| file_of(j) == file_of(i)).collect();
            let points: Vec<[f64; 2]> = same_file
                .iter()
                .flat_map(|&j| contact_points(dataset, j))
                .collect();
            let (centre, along, extent_m) = principal_axis(&points);
            PathSurface {
                recording: i,
                centre,
                height_m: 0.0,
                height_source: Source::Unfitted,
                anchor_m: 0.0,
                follows: same_file.first().copied().filter(|&first| first != i),
                along,
                extent_m,
                slope: 0.0,
                curvature_per_m: 0.0,
                source: Source::Unfitted,
            }
        })
        .collect()
}

/// Whether `path` is recording `leader`'s path or follows it.
pub fn belongs_to(path: &PathSurface, leader: usize) -> bool {
    path.recording == leader || path.follows == Some(leader)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_and_curvature_follow_the_path() {
        let site = SiteSurface {
            site: "center".into(),
            origin: [0.1, 0.0],
            height_m: 0.002,
            source: Source::Training,
        };
        let path = PathSurface {
            recording: 0,
            centre: [0.1, 0.0],
            height_m: 0.0,
            height_source: Source::Training,
            anchor_m: 0.0,
            follows: None,
            along: [1.0, 0.0],
            extent_m: 0.06,
            slope: 0.05,
            curvature_per_m: -4.0,
            source: Source::Training,
        };
        let (z, dz) = shift(Some(&site), Some(&path), [0.12, 0.3], [0.01, 0.5, 0.0]);
        // 2 mm + 0.05 × 2 cm − ½ × 4 × (2 cm)²; rate (0.05 − 4 × 0.02) × 1 cm/s.
        assert!((z - (0.002 + 0.001 - 0.0008)).abs() < 1e-12, "{z}");
        assert!((dz - (0.05 - 0.08) * 0.01).abs() < 1e-12, "{dz}");
        assert_eq!(shift(Some(&site), None, [0.3, 0.3], [1.0; 3]), (0.002, 0.0));
        // Anchored 1 cm before the centre (an onset there), the skin there is site +
        // path height, whatever the slope and curvature.
        let anchored = PathSurface {
            anchor_m: -0.01,
            ..path
        };
        let (z, _) = shift(Some(&site), Some(&anchored), [0.09, 0.0], [0.0; 3]);
        assert!((z - 0.002).abs() < 1e-12, "{z}");
    }
}
