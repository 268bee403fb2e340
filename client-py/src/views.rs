//! Read-only numpy arrays straight onto the observation sample (no copies).
//!
//! Each array's base object is the `NativeLease` that owns the subscriber, so the
//! shared-memory mapping outlives every array. The sample itself is released at the next
//! exchange: an array shows the data of the exchange that returned it until the next
//! `step`/`reset` of its lease, after which its contents are unspecified.

use echogym_protocol::{BatchLayout, DType, ObsField, contiguous_strides};
use numpy::ndarray::{ArrayViewD, IxDyn, ShapeBuilder};
use numpy::{Element, PyArray, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// A read-only array of `T` over `base + offset` with byte strides.
///
/// # Safety
/// The memory must stay mapped while `owner` lives and hold valid `T`s.
unsafe fn view<'py, T: Element>(
    owner: &Bound<'py, PyAny>,
    ptr: *const u8,
    shape: &[usize],
    byte_strides: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let size = std::mem::size_of::<T>();
    let strides: Vec<usize> = byte_strides.iter().map(|s| s / size).collect();
    let view = unsafe {
        ArrayViewD::from_shape_ptr(IxDyn(shape).strides(IxDyn(&strides)), ptr.cast::<T>())
    };
    let array = unsafe { PyArray::borrow_from_array(&view, owner.clone()) };
    unsafe {
        (*array.as_array_ptr()).fields.flags &= !numpy::npyffi::NPY_ARRAY_WRITEABLE;
    }
    Ok(array.into_any())
}

/// The arrays of the observation fields in the block at `block`.
unsafe fn fields<'py>(
    owner: &Bound<'py, PyAny>,
    base: *const u8,
    layout: &BatchLayout,
    block: usize,
    fields: &[ObsField],
) -> PyResult<Bound<'py, PyTuple>> {
    let mut arrays = Vec::with_capacity(fields.len());
    for field in fields {
        let v = layout.field_view(block, field);
        let ptr = unsafe { base.add(v.offset) };
        let array = unsafe {
            match v.dtype {
                DType::Float32 => view::<f32>(owner, ptr, &v.shape, &v.strides)?,
                DType::Uint8 => view::<u8>(owner, ptr, &v.shape, &v.strides)?,
                DType::Int32 => view::<i32>(owner, ptr, &v.shape, &v.strides)?,
            }
        };
        arrays.push(array);
    }
    PyTuple::new(owner.py(), arrays)
}

/// `(obs, reward, terminated, truncated, info, final_obs, final_info)` over the sample
/// at `base`: `obs`/`final_obs` are tuples with one array per field; `final_*` are
/// `None` unless the lease autoresets in the same step.
///
/// # Safety
/// `base` must point at a live observation sample laid out by `layout`.
pub(crate) unsafe fn batch<'py>(
    owner: &Bound<'py, PyAny>,
    base: *const u8,
    layout: &BatchLayout,
    obs_fields: &[ObsField],
) -> PyResult<Bound<'py, PyTuple>> {
    let py = owner.py();
    let k = layout.num_envs;
    let i = layout.info_len;
    let o = &layout.obs;
    unsafe {
        let obs = fields(owner, base, layout, o.obs, obs_fields)?;
        let reward = view::<f32>(owner, base.add(o.reward), &[k], &[4])?;
        let terminated = view::<bool>(owner, base.add(o.terminated), &[k], &[1])?;
        let truncated = view::<bool>(owner, base.add(o.truncated), &[k], &[1])?;
        let info = view::<f32>(
            owner,
            base.add(o.info),
            &[k, i],
            &contiguous_strides(&[k, i], 4),
        )?;
        let final_obs = match o.final_obs {
            Some(block) => fields(owner, base, layout, block, obs_fields)?.into_any(),
            None => py.None().into_bound(py),
        };
        let final_info = match o.final_info {
            Some(at) => view::<f32>(
                owner,
                base.add(at),
                &[k, i],
                &contiguous_strides(&[k, i], 4),
            )?,
            None => py.None().into_bound(py),
        };
        PyTuple::new(
            py,
            [
                obs.into_any(),
                reward,
                terminated,
                truncated,
                info,
                final_obs,
                final_info,
            ],
        )
    }
}
