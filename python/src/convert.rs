//! JSON values (legwork's summaries) to Python objects and back.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;

pub(crate) fn to_python<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_python(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, to_python(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

/// A Python value (dict, list, str, int, float, bool, None) as JSON, for task overrides.
pub(crate) fn from_python(ob: &Bound<'_, PyAny>, path: &str) -> PyResult<Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyString, PyTuple};
    if ob.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = ob.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if ob.is_instance_of::<PyInt>() {
        let i: i64 = ob.extract()?;
        return Ok(Value::from(i));
    }
    if ob.is_instance_of::<PyFloat>() {
        let x: f64 = ob.extract()?;
        return serde_json::Number::from_f64(x).map(Value::Number).ok_or_else(|| crate::errors::input_error(format!("{path}: expected a finite number, got {x}")));
    }
    if let Ok(s) = ob.cast::<PyString>() {
        return Ok(Value::String(s.to_str()?.to_string()));
    }
    if let Ok(d) = ob.cast::<PyDict>() {
        let mut map = serde_json::Map::new();
        for (k, v) in d.iter() {
            let key: String = k.extract().map_err(|_| crate::errors::input_error(format!("{path}: keys must be strings, got {k}")))?;
            let child = format!("{path}.{key}");
            map.insert(key, from_python(&v, &child)?);
        }
        return Ok(Value::Object(map));
    }
    if ob.is_instance_of::<PyList>() || ob.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in ob.try_iter()?.enumerate() {
            items.push(from_python(&item?, &format!("{path}[{i}]"))?);
        }
        return Ok(Value::Array(items));
    }
    // numpy scalars and arrays: through their Python equivalents.
    if ob.hasattr("tolist")? {
        return from_python(&ob.call_method0("tolist")?, path);
    }
    Err(crate::errors::input_error(format!("{path}: expected a TOML-like value (dict, list, str, int, float, bool), got {}", ob.get_type().name()?)))
}
