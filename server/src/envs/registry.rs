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
    /// The id asked for; a longer one is cut to its first 128 characters and its
    /// length (a refusal does not echo megabytes of a client's request back).
    pub id: String,
    /// The registered ids, comma-separated.
    pub known: String,
}

/// The most characters of an unknown id a refusal repeats.
const SHOWN_ID_CHARS: usize = 128;

/// `id`, or its first [`SHOWN_ID_CHARS`] characters and its length.
fn shown(id: &str) -> String {
    match id.char_indices().nth(SHOWN_ID_CHARS) {
        None => id.to_owned(),
        Some((end, _)) => format!("{}… ({} bytes)", &id[..end], id.len()),
    }
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
                id: shown(id),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_id_is_quoted_at_most_to_its_first_characters() {
        let registry = EnvRegistry::default();
        let short = registry.get("echogym/Nope-v0").err().expect("unknown");
        assert_eq!(short.id, "echogym/Nope-v0");
        let long = "é".repeat(100_000);
        let refused = registry.get(&long).err().expect("unknown");
        assert!(refused.id.starts_with(&"é".repeat(SHOWN_ID_CHARS)));
        assert!(
            refused.id.ends_with("… (200000 bytes)"),
            "{}",
            &refused.id[250..]
        );
    }
}
