//! The env registry: versioned ids mapped to factories.
//!
//! Later envs join by registering a factory; the transport never changes.

use std::collections::BTreeMap;

use echogym_protocol::EnvInfo;

use super::arena::ArenaFactory;
use super::calibration_press::CalibrationPress;
use super::factory::EnvFactory;
use super::null::NullEnvFactory;
use super::push_cube::PushCube;
use super::ultrasound_scan::UltrasoundScan;

/// No env is registered under an id.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
#[error("unknown env id {id:?}; registered: {known}")]
pub struct UnknownEnv {
    /// The id asked for.
    pub id: String,
    /// The registered ids, comma-separated.
    pub known: String,
}

/// All registered envs.
pub struct EnvRegistry {
    factories: BTreeMap<&'static str, Box<dyn EnvFactory>>,
}

impl Default for EnvRegistry {
    /// The registry with every built-in env.
    fn default() -> Self {
        let mut registry = Self::empty();
        registry.register(Box::new(NullEnvFactory));
        registry.register(Box::new(ArenaFactory::<UltrasoundScan>::default()));
        registry.register(Box::new(ArenaFactory::<PushCube>::default()));
        registry.register(Box::new(ArenaFactory::<CalibrationPress>::default()));
        registry
    }
}

impl EnvRegistry {
    /// The default registry plus `echogym/Faulty-v0` (tests of fault containment).
    pub fn with_fault_injection() -> Self {
        let mut registry = Self::default();
        registry.register(Box::new(super::faulty::FaultyEnvFactory::default()));
        registry
    }

    /// A registry with no envs.
    pub fn empty() -> Self {
        Self {
            factories: BTreeMap::new(),
        }
    }

    /// Add a factory (replacing one with the same id).
    pub fn register(&mut self, factory: Box<dyn EnvFactory>) {
        self.factories.insert(factory.id(), factory);
    }

    /// The factory for `id`.
    pub fn get(&self, id: &str) -> Result<&dyn EnvFactory, UnknownEnv> {
        self.factories
            .get(id)
            .map(|f| f.as_ref())
            .ok_or_else(|| UnknownEnv {
                id: id.to_owned(),
                known: self
                    .factories
                    .keys()
                    .copied()
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// Every registered env.
    pub fn list(&self) -> Vec<EnvInfo> {
        self.factories
            .values()
            .map(|f| EnvInfo {
                env_id: f.id().to_owned(),
                description: f.description().to_owned(),
            })
            .collect()
    }
}
