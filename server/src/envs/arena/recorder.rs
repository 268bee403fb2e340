//! [`EpisodeRecorder`]: records episodes of a physics env to the calibration tool's
//! format (`echogym-recordings/1`), one dataset per env instance, one CSV per episode,
//! sampled every physics step. CSVs are written by the dataset writer's background
//! thread; the dataset appears atomically when the env is dropped (lease detached).

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::recordings::{DatasetWriter, Recording};
use crate::sim::scene::Scene;
use crate::sim::world::{arr3, vec3};

/// Numbers env instances within this process (dataset folder names).
static INSTANCES: AtomicU64 = AtomicU64::new(0);

/// Records episodes while a budget of episodes lasts.
pub struct EpisodeRecorder {
    target: PathBuf,
    description: String,
    writer: Option<DatasetWriter>,
    current: Recording,
    site: String,
    protocol: String,
    recorded: usize,
    budget: usize,
}

impl EpisodeRecorder {
    /// A recorder writing `<dir>/<slug>-<pid>-<instance>` for `budget` episodes.
    pub fn new(dir: &std::path::Path, env_id: &str, budget: usize) -> Self {
        let slug = env_id.replace('/', "-");
        let instance = INSTANCES.fetch_add(1, Ordering::Relaxed);
        Self {
            target: dir.join(format!("{slug}-{}-{instance}", std::process::id())),
            description: format!("episodes of {env_id} recorded by echogym"),
            writer: None,
            current: Recording::default(),
            site: String::new(),
            protocol: String::new(),
            recorded: 0,
            budget,
        }
    }

    /// Start an episode at `site` with `protocol` (the previous one, if any, is queued).
    pub fn begin(&mut self, scene: &Scene, site: &str, protocol: &str) {
        self.end();
        if self.recorded >= self.budget {
            return;
        }
        if self.writer.is_none() {
            let (surface, centre) = scene
                .torso()
                .map_or((scene.params().world.table.top_z, [0.0; 2]), |t| {
                    (t.params().top_z(), t.params().center_xy)
                });
            match DatasetWriter::create(&self.target, &self.description, surface, centre) {
                Ok(writer) if !writer.inside_recordings_root() => {
                    tracing::warn!(
                        "recording disabled: {} leads outside the recordings root through a symbolic link",
                        self.target.display()
                    );
                    drop(writer);
                    self.budget = 0;
                    return;
                }
                Ok(mut writer) => {
                    writer.meta_mut().torso = scene
                        .params()
                        .torso
                        .as_ref()
                        .and_then(|t| serde_json::to_value(t).ok());
                    self.writer = Some(writer);
                }
                Err(e) => {
                    tracing::warn!("recording disabled: {e}");
                    self.budget = 0;
                    return;
                }
            }
        }
        self.site = site.to_owned();
        self.protocol = protocol.to_owned();
        self.sample(scene);
    }

    /// Append the scene's current state (call after each physics step).
    pub fn sample(&mut self, scene: &Scene) {
        if self.writer.is_none() || self.recorded >= self.budget {
            return;
        }
        let tip = scene.tip_pose();
        let (v, _) = scene.tip_velocity();
        let reading = scene.ft_reading();
        // The sensor reads the tool's load in its frame; the body's force on the probe in
        // the world frame is that load rotated to the world.
        let f = arr3(tip.rotation * vec3([reading[0], reading[1], reading[2]]));
        let t = arr3(tip.rotation * vec3([reading[3], reading[4], reading[5]]));
        let r = &mut self.current;
        r.t.push(scene.time());
        r.p.push(arr3(tip.translation));
        r.v.push(v);
        r.f.push(f);
        r.torque.get_or_insert_with(Vec::new).push(t);
    }

    /// Queue the current episode (if it has at least two samples).
    pub fn end(&mut self) {
        let recording = std::mem::take(&mut self.current);
        if recording.len() < 2 {
            return;
        }
        if let Some(writer) = &mut self.writer {
            self.recorded += 1;
            let file = format!("episode_{:05}.csv", self.recorded);
            writer.add(&file, &self.site, &self.protocol, recording);
        }
    }
}

impl Drop for EpisodeRecorder {
    fn drop(&mut self) {
        self.end();
        if let Some(writer) = self.writer.take() {
            match writer.finish() {
                Ok(path) => tracing::info!("recorded dataset {}", path.display()),
                Err(e) => tracing::warn!("recording failed: {e}"),
            }
        }
    }
}
