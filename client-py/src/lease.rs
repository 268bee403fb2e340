//! `NativeLease`: a leased batch of envs with zero-copy observation views.

use std::sync::{Arc, Mutex};

use echogym_client::Lease;
use echogym_protocol::{BatchLayout, ObsField};
use numpy::{PyReadonlyArray1, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::errors::{InvalidActionError, lease_error};
use crate::views;

/// Views cached per sample slot; the publisher cycles through a few fixed slots.
const VIEW_CACHE_SLOTS: usize = 16;

/// The base object of every observation array: keeps the lease (and so the mapping of
/// its shared memory) alive while any array exists. Separate from [`NativeLease`] so that
/// the view cache does not form a reference cycle the garbage collector cannot see.
#[pyclass(module = "echogym._native", frozen)]
pub struct SampleMemory {
    _owner: Arc<dyn std::any::Any + Send + Sync>,
}

impl SampleMemory {
    /// The base object of views into samples that `owner` (a lease or an async batch
    /// behind a mutex) keeps mapped.
    pub(crate) fn keeping<T: Send + 'static>(owner: Arc<Mutex<T>>) -> Self {
        Self { _owner: owner }
    }
}

/// A leased batch of envs on the server.
#[pyclass(module = "echogym._native", frozen)]
pub struct NativeLease {
    lease: Arc<Mutex<Lease>>,
    memory: Py<SampleMemory>,
    layout: BatchLayout,
    fields: Vec<ObsField>,
    spec_json: String,
    layout_json: String,
    cache: Mutex<Vec<(usize, Py<PyTuple>)>>,
}

impl NativeLease {
    pub(crate) fn new(py: Python<'_>, lease: Lease) -> PyResult<Self> {
        let lease = Arc::new(Mutex::new(lease));
        let memory = Py::new(py, SampleMemory::keeping(lease.clone()))?;
        let this = lease.lock().unwrap_or_else(|p| p.into_inner());
        Ok(Self {
            layout: this.layout().clone(),
            fields: this.spec().observation.clone(),
            spec_json: serde_json::to_string(this.spec()).expect("spec serializes"),
            layout_json: serde_json::to_string(this.layout()).expect("layout serializes"),
            lease: lease.clone(),
            memory,
            cache: Mutex::new(Vec::new()),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Lease> {
        self.lease.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The view tuple for the sample at `ptr`, cached per slot.
    fn views<'py>(slf: &Bound<'py, Self>, ptr: usize) -> PyResult<Bound<'py, PyTuple>> {
        let this = slf.get();
        let py = slf.py();
        let mut cache = this.cache.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, tuple)) = cache.iter().find(|(p, _)| *p == ptr) {
            return Ok(tuple.bind(py).clone());
        }
        // SAFETY: `ptr` is the payload of the sample the lease holds; the mapping lives
        // as long as the lease's subscriber, which the arrays' base (`memory`) keeps.
        let owner = this.memory.bind(py).clone().into_any();
        let tuple = unsafe { views::batch(&owner, ptr as *const u8, &this.layout, &this.fields)? };
        if cache.len() >= VIEW_CACHE_SLOTS {
            cache.remove(0);
        }
        cache.push((ptr, tuple.clone().unbind()));
        Ok(tuple)
    }
}

#[pymethods]
impl NativeLease {
    /// Step every env with `actions`, a float32 array of shape `(num_envs, action_size)`.
    /// Returns `(obs, reward, terminated, truncated, info, final_obs, final_info)` as
    /// read-only views valid until the next exchange of this lease.
    fn step<'py>(
        slf: &Bound<'py, Self>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let this = slf.get();
        let array: PyReadonlyArrayDyn<'py, f32> = actions.extract().map_err(|_| {
            InvalidActionError::new_err(format!(
                "actions must be a float32 numpy array of shape ({}, {}), got {}",
                this.layout.num_envs,
                this.layout.action_size,
                describe(actions)
            ))
        })?;
        let expected = [this.layout.num_envs, this.layout.action_size];
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
        let ptr = slf
            .py()
            .detach(|| this.lock().step(actions, None).map(|p| p.as_ptr() as usize))
            .map_err(lease_error)?;
        Self::views(slf, ptr)
    }

    /// Reset the envs where `mask` is true (all when `None`); `seeds` is a list with one
    /// seed or `None` per env. Returns the same tuple as `step` (rewards and flags zero).
    #[pyo3(signature = (mask = None, seeds = None))]
    fn reset<'py>(
        slf: &Bound<'py, Self>,
        mask: Option<PyReadonlyArray1<'py, bool>>,
        seeds: Option<Vec<Option<u64>>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let this = slf.get();
        let mask: Option<Vec<bool>> = mask.map(|m| m.as_array().to_vec());
        let ptr = slf
            .py()
            .detach(|| {
                this.lock()
                    .reset(mask.as_deref(), seeds.as_deref())
                    .map(|p| p.as_ptr() as usize)
            })
            .map_err(lease_error)?;
        Self::views(slf, ptr)
    }

    /// Give the lease back. Idempotent. Arrays already returned stay readable.
    fn close(&self, py: Python<'_>) {
        py.detach(|| self.lock().close());
    }

    /// True once closed (by `close` or because the server stopped).
    #[getter]
    fn closed(&self) -> bool {
        self.lock().is_closed()
    }

    /// The lease id.
    #[getter]
    fn lease_id(&self) -> u64 {
        self.lock().id()
    }

    /// Envs in the batch.
    #[getter]
    fn num_envs(&self) -> usize {
        self.layout.num_envs
    }

    /// The env spec as JSON.
    #[getter]
    fn spec_json(&self) -> &str {
        &self.spec_json
    }

    /// The batch layout as JSON.
    #[getter]
    fn layout_json(&self) -> &str {
        &self.layout_json
    }
}

fn describe(value: &Bound<'_, PyAny>) -> String {
    let dtype = value
        .getattr("dtype")
        .map(|d| d.to_string())
        .unwrap_or_else(|_| value.get_type().to_string());
    let shape = value
        .getattr("shape")
        .map(|s| s.to_string())
        .unwrap_or_default();
    format!("{dtype} {shape}").trim().to_owned()
}
