//! `echogym calibrate`: sim-to-real calibration that locates the mismatch, names the
//! physics the simulator left out, models it in the simulator and shows the fit improve —
//! or says plainly that something the catalogue lacks remains.
//!
//! Pipeline ([`calibrate`]), one stage per file:
//! 1. [`split`]: whole recordings into train (fitting), validation (choosing effects) and
//!    test (judging only), seeded.
//! 2. [`baseline`]: echogym's particle torso ([`replay`]) with stiffness, damping and the
//!    body's surface per site ([`geometry`]) fitted by output-error least squares on the
//!    train recordings ([`model`], [`fit`]).
//! 3. [`mismatch`]: where the baseline's residual lives (recording and span, phase,
//!    depth and velocity region, frequency band), against the noise floor ([`noise`]).
//! 4. [`select`]: the catalogue's signatures ([`effects`]) fitted on the train residual,
//!    forward selection gated on the validation recordings, each further effect needing
//!    stronger evidence than the one before; each accepted effect is modelled as a
//!    simulator element, everything is refitted by replay ([`model`]) and the simulator
//!    itself must beat the previous one on validation.
//! 5. [`unexplained`]: is the calibrated residual noise? If not, where it lives.
//! 6. [`report`]: test before/after, intervals, geometry, verdict, replays.

pub mod baseline;
pub mod decision;
pub mod effects;
pub mod features;
pub mod fit;
pub mod free_air;
pub mod gain;
pub mod geometry;
pub mod high_pass;
pub mod lateral_share;
pub mod lone_protocol;
pub mod mismatch;
pub mod model;
pub mod noise;
pub mod on_trust;
pub mod onset;
pub mod onset_geometry;
pub mod replay;
pub mod report;
pub mod select;
pub mod session;
pub mod share_gradient;
pub mod simpler;
pub mod split;
pub mod synth;
pub mod thesis_method;
pub mod touch_down;
pub mod trajectory;
pub mod unexplained;
pub mod weighing;

use std::path::{Path, PathBuf};

use crate::recordings::{Dataset, RecordingsError};
use features::Series;
use model::FitDiagnostics;
use replay::{Model, Setup};
use split::Split;

/// Why calibration failed.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The dataset is invalid (names the file and row).
    #[error(transparent)]
    Dataset(#[from] RecordingsError),
    /// The dataset's `torso` overrides are invalid.
    #[error("dataset.json `torso`: {0}")]
    Torso(String),
    /// The dataset cannot be calibrated.
    #[error("cannot calibrate: {0}")]
    Unusable(String),
    /// Writing the outputs failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Options of a run.
#[derive(Debug, Clone)]
pub struct CalibrateOptions {
    /// The dataset folder.
    pub dataset: PathBuf,
    /// The output folder (created; files inside replaced).
    pub out: PathBuf,
    /// Seed of the train/held-out split.
    pub seed: u64,
    /// Draw a progress bar on stderr.
    pub progress: bool,
}

/// Progress on stderr: a bar (indicatif) on a terminal, one plain line per stage in a
/// pipe or log file (no escape codes there).
struct Progress {
    bar: Option<indicatif::ProgressBar>,
    /// Stages in all; 0 when progress is off.
    total: usize,
    done: usize,
}

impl Progress {
    fn new(enabled: bool, total: usize) -> Self {
        let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
        let bar = (enabled && terminal).then(|| {
            let bar = indicatif::ProgressBar::new(total as u64);
            if let Ok(style) =
                indicatif::ProgressStyle::with_template("[{bar:30}] {pos}/{len} {msg}")
            {
                bar.set_style(style.progress_chars("#>."));
            }
            bar
        });
        Self {
            bar,
            total: if enabled { total } else { 0 },
            done: 0,
        }
    }

    fn stage(&mut self, what: &str) {
        if self.total == 0 {
            return;
        }
        match &self.bar {
            Some(bar) => {
                bar.set_position(self.done as u64);
                bar.set_message(what.to_owned());
            }
            None => eprintln!("[{}/{}] {what}", self.done + 1, self.total),
        }
        self.done += 1;
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_with_message("done");
        }
    }
}

/// Everything the report is made of (see [`report`]).
pub struct Outcome {
    /// Dataset read.
    pub dataset: Dataset,
    /// Train, validation and test recordings.
    pub split: Split,
    /// Files cut in two so their protocol has a validation part.
    pub lent: Vec<lone_protocol::Lent>,
    /// Baseline model.
    pub baseline: Model,
    /// What the baseline's fit says about itself.
    pub baseline_fit: FitDiagnostics,
    /// Sites whose surface was fitted on held-out recordings (no training recording).
    pub surface_from_heldout: Vec<String>,
    /// Calibrated model.
    pub calibrated: Model,
    /// What the final fit says about itself (the baseline's when no effect was named).
    pub calibrated_fit: FitDiagnostics,
    /// Per recording, baseline series (prediction and residual).
    pub series: Vec<Series>,
    /// Calibrated prediction per recording.
    pub calibrated_fz: Vec<Vec<f64>>,
    /// Calibrated sideways prediction (`fx, fy`) per recording.
    pub calibrated_fxy: Vec<Vec<[f64; 2]>>,
    /// Noise floor \[N\].
    pub noise: f64,
    /// How the noise floor was measured.
    pub noise_source: noise::NoiseSource,
    /// Where the baseline misses.
    pub mismatch: mismatch::Mismatch,
    /// Accepted effects: (name, params, evidence, validation RMSE after the surrogate).
    pub accepted: Vec<decision::Accepted>,
    /// Rejected candidates with reasons.
    pub rejected: Vec<decision::Rejected>,
    /// Whether something the catalogue lacks remains, and where.
    pub verdict: unexplained::Verdict,
    /// The seed's regression per site.
    pub thesis_method: Vec<thesis_method::ThesisFit>,
    /// The setup.
    pub setup: Setup,
    /// Contact stiffness of the baseline [N/m].
    pub k_eff: f64,
}

/// Run the whole calibration and write the outputs into `options.out`.
pub fn calibrate(options: &CalibrateOptions) -> Result<Outcome, CalibrateError> {
    let mut progress = Progress::new(options.progress, 6);
    progress.stage("reading the dataset");
    let mut dataset = Dataset::read(&options.dataset)?;
    for rec in &mut dataset.recordings {
        *rec = trajectory::smoothed(rec);
    }
    let mut sources: Vec<&str> = dataset
        .meta
        .recordings
        .iter()
        .map(|e| {
            e.segment
                .as_ref()
                .map_or(e.file.as_str(), |s| s.source.as_str())
        })
        .collect();
    sources.dedup();
    if sources.len() < 2 {
        return Err(CalibrateError::Unusable(format!(
            "{} holds {} recording file(s); at least 2 are needed (train and held-out)",
            options.dataset.display(),
            sources.len()
        )));
    }
    let lent = lone_protocol::lend(&mut dataset);
    let n = dataset.recordings.len();
    let setup = baseline::setup(&dataset)?;
    let split = split::split(&dataset, options.seed, &lent);
    let all: Vec<usize> = (0..n).collect();

    progress.stage("fitting the baseline and the surface per site (replaying the simulator)");
    let fitted = baseline::fit(&setup, &dataset, &split);
    let mut base = fitted.model.clone();
    let k_per_unit = baseline::static_stiffness(&setup.torso) / setup.torso.stiffness;
    let k_eff = base.stiffness * k_per_unit;

    progress.stage("replaying every recording with the baseline");
    // Twice: the second adds each site's tangential share read on the first (the body's
    // replay is reused; the share is a sensor-side term).
    let cache = replay::ReplayCache::new(n);
    let predictions = cache.replay_all(&setup, &base, &dataset.recordings, &all);
    let sites: Vec<String> = setup.sites.iter().map(|(name, _)| name.clone()).collect();
    let mut train = vec![false; n];
    split.train.iter().for_each(|&i| train[i] = true);
    (base.site_lateral_share, base.lateral_share_gradient) =
        lateral_share::site_shares(&series_of(&dataset, &setup, &predictions), &train, &sites);
    let predictions = cache.replay_all(&setup, &base, &dataset.recordings, &all);
    let series = series_of(&dataset, &setup, &predictions);
    let (noise, noise_source) = noise::noise_floor(&series);

    progress.stage("locating the mismatch");
    let located = mismatch::locate(&series);

    progress.stage("naming effects: validation tests of the catalogue, each modelled and refitted in the simulator");
    let selected = select::select(&select::Inputs {
        dataset: &dataset,
        setup: &setup,
        split: &split,
        baseline: &base,
        baseline_fit: &fitted.diagnostics,
        series: &series,
        predictions: &predictions,
        noise,
        k_per_unit,
    });
    let select::Selection {
        calibrated,
        calibrated_fit,
        accepted,
        rejected,
        verdict,
        calibrated_fz,
        calibrated_fxy,
    } = selected;

    progress.stage("writing the report");
    let thesis_fits = thesis_method::thesis_method(&series, -base.surface_offset);
    let outcome = Outcome {
        dataset,
        split,
        lent,
        baseline: base,
        baseline_fit: fitted.diagnostics,
        surface_from_heldout: fitted.surface_from_heldout,
        calibrated,
        calibrated_fit,
        series,
        calibrated_fz,
        calibrated_fxy,
        noise,
        noise_source,
        mismatch: located,
        accepted,
        rejected,
        verdict,
        thesis_method: thesis_fits,
        setup,
        k_eff,
    };
    report::write(&outcome, &options.out)?;
    progress.finish();
    Ok(outcome)
}

/// Every recording with a prediction of it (predictions in recording order).
fn series_of(dataset: &Dataset, setup: &Setup, predictions: &[replay::Prediction]) -> Vec<Series> {
    let file_of = |e: &crate::recordings::RecordingEntry| {
        e.segment
            .as_ref()
            .map_or(e.file.clone(), |s| s.source.clone())
    };
    let mut series: Vec<Series> = dataset
        .meta
        .recordings
        .iter()
        .zip(&dataset.recordings)
        .zip(predictions)
        .enumerate()
        .map(|(i, ((e, rec), p))| {
            let site_index = setup
                .sites
                .iter()
                .position(|(name, _)| *name == e.site)
                .unwrap_or(0);
            Series::new(i, e, site_index, rec, p, &setup.session)
        })
        .collect();
    // A later segment without an onset stands on its file's first segment's skin.
    for i in 0..series.len() {
        let leader = (0..series.len())
            .find(|&j| file_of(&dataset.meta.recordings[j]) == file_of(&dataset.meta.recordings[i]))
            .unwrap_or(i);
        series[i].placed_by = onset::median_onset(&series[i].onsets, 0.0)
            .or_else(|| onset::median_onset(&series[leader].onsets, 0.0));
    }
    series
}

/// Path helper for outputs.
pub(crate) fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> CalibrateError + '_ {
    move |source| CalibrateError::Io {
        path: path.to_owned(),
        source,
    }
}
