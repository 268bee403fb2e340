//! The baseline: echogym's torso as the dataset describes it, with its stiffness,
//! damping and the body's surface (globally, then per site) fitted by replay. Nothing
//! here is ever named as an effect.

use super::session::SessionClock;
use crate::recordings::Dataset;
use crate::sim::torso::{ProbeFace, Torso, TorsoParams};

use super::CalibrateError;
use super::fit::Effort;
use super::geometry::{self, Source};
use super::model::{FitDiagnostics, Free, Geometry, fit_model};
use super::onset;
use super::onset_geometry;
use super::replay::{Model, OnsetAnchor, Setup};
use super::split::Split;

/// LM iterations of the global stage (stiffness, damping, one surface height).
const GLOBAL_ITERATIONS: usize = 3;
/// LM iterations of the per-site stage.
const SITE_ITERATIONS: usize = 8;

/// The dataset's scene: default torso with the dataset's overrides, placed at its
/// centre; sites where the probe touched.
pub fn setup(dataset: &Dataset) -> Result<Setup, CalibrateError> {
    let meta = &dataset.meta;
    let mut torso = TorsoParams::default();
    if let Some(over) = &meta.torso {
        let mut base = serde_json::to_value(&torso).expect("TorsoParams serializes");
        if let (Some(b), Some(o)) = (base.as_object_mut(), over.as_object()) {
            for (k, v) in o {
                b.insert(k.clone(), v.clone());
            }
        }
        torso = serde_json::from_value(base).map_err(|e| CalibrateError::Torso(e.to_string()))?;
        torso
            .validate()
            .map_err(|e| CalibrateError::Torso(e.to_string()))?;
    }
    torso.center_xy = meta.torso_center_xy;
    Ok(Setup {
        torso,
        nominal_surface_z: meta.nominal_surface_z,
        center_xy: meta.torso_center_xy,
        sites: geometry::sites(dataset)
            .into_iter()
            .map(|s| (s.site, s.origin))
            .collect(),
        recording_sites: meta.recordings.iter().map(|e| e.site.clone()).collect(),
        session: SessionClock::of(dataset),
        approaches: dataset.recordings.iter().map(onset::approaches).collect(),
    })
}

/// Static stiffness [N/m] of `torso` under the default probe at its centre, 5 mm deep.
pub fn static_stiffness(torso: &TorsoParams) -> f64 {
    Torso::new(torso.clone(), ProbeFace::default())
        .map_or(1729.0, |t| t.static_probe_stiffness(torso.center_xy, 0.005))
}

/// `Σ F·r / Σ r²` over train samples more than 2 mm below the nominal surface [N/m].
fn initial_stiffness(dataset: &Dataset, train: &[usize], setup: &Setup) -> f64 {
    let (mut fr, mut rr) = (0.0, 0.0);
    for &i in train {
        let rec = &dataset.recordings[i];
        for (p, f) in rec.p.iter().zip(&rec.f) {
            let r = setup.nominal_surface_z - p[2];
            if r > 0.002 {
                fr += f[2] * r;
                rr += r * r;
            }
        }
    }
    if rr > 0.0 { fr / rr } else { 1729.0 }
}

/// The fitted baseline and what its fit says about itself.
pub struct Baseline {
    /// The model.
    pub model: Model,
    /// The per-site stage's diagnostics.
    pub diagnostics: FitDiagnostics,
    /// Sites without a training recording whose surface was fitted on their own
    /// (held-out) recordings.
    pub surface_from_heldout: Vec<String>,
}

/// Fit the baseline on the training recordings: stiffness, damping and one surface
/// height first, then every site's surface with stiffness and damping again.
pub fn fit(setup: &Setup, dataset: &Dataset, split: &Split) -> Baseline {
    let k_per_unit = static_stiffness(&setup.torso) / setup.torso.stiffness;
    let k0 = initial_stiffness(dataset, &split.train, setup) / k_per_unit;
    let mut start = Model::baseline(k0.clamp(100.0, 20_000.0), setup.torso.damping, 0.0);
    // The skin's friction as configured (echogym's default gel-coupled skin unless the
    // dataset's `torso` says otherwise): `sliding_friction` is friction beyond it.
    start.friction = setup.torso.friction;
    start.surface = geometry::sites(dataset);
    start.paths = geometry::paths(dataset);
    // The skin where the contact onsets put it; their median becomes the global surface
    // offset's starting value (it stays fitted: the particle torso's own contact may sit
    // a little off the data's).
    for (entry, found) in dataset.meta.recordings.iter().zip(&setup.approaches) {
        let at = onset::median_onset(found, 0.0).map(|a| (a.z, a.speed));
        tracing::debug!(
            "contact onset of {} (height, speed down): {at:?}",
            entry.file
        );
    }
    if let Some(reference) = onset_geometry::place(setup, &mut start, &|_| 0.0) {
        start.surface_offset = reference - dataset.meta.nominal_surface_z;
        start.onset_anchor = Some(OnsetAnchor {
            offset_m: start.surface_offset,
            speed_m_per_s: onset::reference_speed(setup.approaches.iter().map(Vec::as_slice)),
        });
    }
    let global = Free {
        physics: true,
        stiffness: true,
        offset: true,
        geometry: Geometry::Fixed,
        above_hz: None,
        free_air: false,
    };
    let (model, _) = fit_model(
        setup,
        dataset,
        &split.train,
        start,
        &[],
        global,
        // Only a start for the per-site stage.
        Effort::iterations(GLOBAL_ITERATIONS, false),
    );
    let (model, diagnostics) = fit_model(
        setup,
        dataset,
        &split.train,
        model,
        &[],
        Free::PER_SITE,
        Effort::iterations(SITE_ITERATIONS, true),
    );
    let (model, surface_from_heldout) = surface_elsewhere(setup, dataset, split, model);
    Baseline {
        model,
        diagnostics,
        surface_from_heldout,
    }
}

/// The surface the training recordings could not determine — a site without a
/// training recording, or a slide at a site trained only on presses — fitted on the
/// held-out recordings that show it, with everything else held (a per-site nuisance,
/// like a breathing phase: the physics stays what the training recordings say).
/// Returns the sites and paths so fitted.
pub fn surface_elsewhere(
    setup: &Setup,
    dataset: &Dataset,
    split: &Split,
    model: Model,
) -> (Model, Vec<String>) {
    let heldout = split.heldout();
    let undetermined = |i: usize| {
        let site = &dataset.meta.recordings[i].site;
        model
            .surface_at(site)
            .is_some_and(|g| !matches!(g.source, Source::Training | Source::Onset))
            || model
                .paths
                .iter()
                .any(|p| p.recording == i && p.has_slope() && p.source != Source::Training)
    };
    let elsewhere: Vec<usize> = heldout.into_iter().filter(|&i| undetermined(i)).collect();
    if elsewhere.is_empty() {
        return (model, Vec::new());
    }
    let geometry_only = Free {
        physics: false,
        stiffness: false,
        offset: false,
        geometry: Geometry::Undetermined,
        above_hz: None,
        free_air: false,
    };
    let (model, _) = fit_model(
        setup,
        dataset,
        &elsewhere,
        model,
        &[],
        geometry_only,
        // Nuisances: their intervals are not reported.
        Effort::iterations(SITE_ITERATIONS, false),
    );
    let mut sites: Vec<String> = model
        .surface
        .iter()
        .filter(|g| g.source == Source::Heldout)
        .map(|g| g.site.clone())
        .collect();
    sites.extend(
        model
            .paths
            .iter()
            .filter(|p| p.source == Source::Heldout)
            .map(|p| format!("path of {}", dataset.meta.recordings[p.recording].file)),
    );
    (model, sites)
}
