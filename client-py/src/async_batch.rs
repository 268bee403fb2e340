//! `NativeAsyncBatch`: envpool-style asynchronous groups of envs with zero-copy views.

use std::sync::{Arc, Mutex};

use echogym_client::AsyncBatch;
use echogym_protocol::{BatchLayout, ObsField};
use numpy::{PyReadonlyArray1, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::errors::{InvalidActionError, lease_error};
use crate::lease::SampleMemory;
use crate::views;

/// Views cached per sample slot of each group (the publishers cycle a few fixed slots).
const VIEW_CACHE_SLOTS_PER_GROUP: usize = 16;

/// `num_envs` envs leased as groups of `group_size`, stepped asynchronously.
#[pyclass(module = "echogym._native", frozen)]
pub struct NativeAsyncBatch {
    batch: Arc<Mutex<AsyncBatch>>,
    memory: Py<SampleMemory>,
    layout: BatchLayout,
    fields: Vec<ObsField>,
    spec_json: String,
    layout_json: String,
    num_envs: usize,
    group_size: usize,
    cache: Mutex<Vec<(usize, Py<PyTuple>)>>,
}

impl NativeAsyncBatch {
    pub(crate) fn new(py: Python<'_>, batch: AsyncBatch) -> PyResult<Self> {
        let layout = batch.layout().clone();
        let fields = batch.spec().observation.clone();
        let spec_json = serde_json::to_string(batch.spec()).expect("spec serializes");
        let layout_json = serde_json::to_string(batch.layout()).expect("layout serializes");
        let (num_envs, group_size) = (batch.num_envs(), batch.group_size());
        let batch = Arc::new(Mutex::new(batch));
        let memory = Py::new(py, SampleMemory::keeping(batch.clone()))?;
        Ok(Self {
            batch,
            memory,
            layout,
            fields,
            spec_json,
            layout_json,
            num_envs,
            group_size,
            cache: Mutex::new(Vec::new()),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, AsyncBatch> {
        self.batch.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn env_ids(ids: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
        if let Ok(array) = ids.extract::<PyReadonlyArray1<'_, i64>>() {
            return array
                .as_array()
                .iter()
                .map(|&i| {
                    usize::try_from(i).map_err(|_| {
                        pyo3::exceptions::PyValueError::new_err(format!("env id {i} is negative"))
                    })
                })
                .collect();
        }
        ids.extract::<Vec<usize>>().map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(
                "env_ids must be a sequence or int64 array of non-negative env ids",
            )
        })
    }
}

#[pymethods]
impl NativeAsyncBatch {
    /// Step the envs `env_ids` with `actions` (float32, shape `(len(env_ids),
    /// action_size)`, row `i` for env `env_ids[i]`) and return at once. `env_ids` must be
    /// whole groups whose observations were received (what `recv` returned).
    fn send_step(
        &self,
        py: Python<'_>,
        actions: &Bound<'_, PyAny>,
        env_ids: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let ids = Self::env_ids(env_ids)?;
        let array: PyReadonlyArrayDyn<'_, f32> = actions.extract().map_err(|_| {
            InvalidActionError::new_err(format!(
                "actions must be a float32 numpy array of shape ({}, {})",
                ids.len(),
                self.layout.action_size
            ))
        })?;
        let expected = [ids.len(), self.layout.action_size];
        if array.shape() != expected {
            return Err(InvalidActionError::new_err(format!(
                "actions must have shape ({}, {}), got {:?}",
                expected[0],
                expected[1],
                array.shape()
            )));
        }
        let owned;
        let actions: &[f32] = match array.as_slice() {
            Ok(slice) => slice,
            Err(_) => {
                owned = array.as_array().iter().copied().collect::<Vec<f32>>();
                &owned
            }
        };
        py.detach(|| self.lock().send_step(actions, &ids))
            .map_err(lease_error)
    }

    /// Reset the envs `env_ids` (whole groups), `seeds` one int or `None` per id, and
    /// return at once.
    #[pyo3(signature = (env_ids, seeds = None))]
    fn send_reset(
        &self,
        py: Python<'_>,
        env_ids: &Bound<'_, PyAny>,
        seeds: Option<Vec<Option<u64>>>,
    ) -> PyResult<()> {
        let ids = Self::env_ids(env_ids)?;
        py.detach(|| self.lock().send_reset(&ids, seeds.as_deref()))
            .map_err(lease_error)
    }

    /// Wait until at least `min_envs` envs' observations are in (all pending when fewer)
    /// and return their groups, first arrived first (the GIL is released meanwhile).
    fn recv(&self, py: Python<'_>, min_envs: usize) -> PyResult<Vec<usize>> {
        py.detach(|| self.lock().recv(min_envs))
            .map_err(lease_error)
    }

    /// The last received observations of `group` as the `(obs, reward, terminated,
    /// truncated, info, final_obs, final_info)` views of `NativeLease.step` (`group_size`
    /// rows), valid until the group is sent again.
    fn views<'py>(slf: &Bound<'py, Self>, group: usize) -> PyResult<Bound<'py, PyTuple>> {
        let this = slf.get();
        let py = slf.py();
        let ptr = {
            let batch = this.lock();
            if group >= batch.num_groups() {
                return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                    "group {group} out of range (0..{})",
                    batch.num_groups()
                )));
            }
            match batch.lease(group).current() {
                Some(payload) => payload.as_ptr() as usize,
                None => {
                    return Err(pyo3::exceptions::PyValueError::new_err(format!(
                        "group {group} has no received observation (send it, then recv)"
                    )));
                }
            }
        };
        let mut cache = this.cache.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, tuple)) = cache.iter().find(|(p, _)| *p == ptr) {
            return Ok(tuple.bind(py).clone());
        }
        // SAFETY: `ptr` is the payload of the sample the group's lease holds; the mapping
        // lives as long as the lease's subscriber, which the arrays' base keeps.
        let owner = this.memory.bind(py).clone().into_any();
        let tuple = unsafe { views::batch(&owner, ptr as *const u8, &this.layout, &this.fields)? };
        let capacity = VIEW_CACHE_SLOTS_PER_GROUP * (this.num_envs / this.group_size);
        if cache.len() >= capacity {
            cache.remove(0);
        }
        cache.push((ptr, tuple.clone().unbind()));
        Ok(tuple)
    }

    /// Envs sent whose observations `recv` has not returned yet.
    #[getter]
    fn pending_envs(&self) -> usize {
        self.lock().pending_envs()
    }

    /// Give every group's lease back. Idempotent.
    fn close(&self, py: Python<'_>) {
        py.detach(|| self.lock().close());
    }

    /// All envs.
    #[getter]
    fn num_envs(&self) -> usize {
        self.num_envs
    }

    /// Envs per group.
    #[getter]
    fn group_size(&self) -> usize {
        self.group_size
    }

    /// The env spec as JSON.
    #[getter]
    fn spec_json(&self) -> &str {
        &self.spec_json
    }

    /// One group's batch layout as JSON.
    #[getter]
    fn layout_json(&self) -> &str {
        &self.layout_json
    }
}
