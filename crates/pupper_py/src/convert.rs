//! Python values into the Rust request: keyword options into a
//! [`SweepSpec`], grids into a [`GridInput`], `out` into a path; a
//! command's own keywords taken one by one ([`Keywords`]); a report back as
//! a dict.

use std::path::PathBuf;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyString};

use pupper_core::request::spec::{AxisInput, GridInput, SweepSpec};

use crate::error::{ConfigError, GridError, InternalError, OutputError};

/// A serializable report as a dict of plain Python values.
pub(crate) fn to_dict<'py, T: serde::Serialize>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    // ±inf as Python's floats (serde_json writes null, losing the sign)
    let text = pupper_core::results::json::to_python_text(v)
        .map_err(|e| InternalError::new_err(e.to_string()))?;
    PyModule::import(py, "json")?
        .getattr("loads")?
        .call1((text,))
}

/// Whether keyword `k` is among `options`.
pub(crate) fn given(options: Option<&Bound<'_, PyDict>>, k: &str) -> bool {
    options.is_some_and(|o| o.contains(k).unwrap_or(false))
}

/// The spec from Python keyword arguments: their names are the fields of
/// [`SweepSpec`] and what is not given keeps the spec's default. They cross
/// as JSON (floats round-trip exactly), so a wrong type names its keyword.
pub(crate) fn spec_from(
    py: Python<'_>,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<SweepSpec> {
    let Some(options) = options else {
        return Ok(SweepSpec::default());
    };
    // a float that is not finite, named by its keyword (JSON cannot say which)
    for (k, v) in options.iter() {
        let bad = |x: f64| !x.is_finite();
        let nonfinite = match v.extract::<f64>() {
            Ok(x) => bad(x),
            Err(_) => v
                .extract::<Vec<f64>>()
                .is_ok_and(|xs| xs.iter().copied().any(bad)),
        };
        if nonfinite && !v.is_instance_of::<PyBool>() {
            return Err(ConfigError::new_err(format!(
                "{k}={} is not a finite number: give {k} a finite value",
                v.repr()?
            )));
        }
    }
    let kw = PyDict::new(py);
    kw.set_item("allow_nan", false)?;
    // numpy's numbers and arrays (np.float32(60), np.array([...])) are the
    // plain values their tolist() gives
    let tolist = PyModule::import(py, "operator")?
        .getattr("methodcaller")?
        .call1(("tolist",))?;
    kw.set_item("default", tolist)?;
    let dumps = PyModule::import(py, "json")?.getattr("dumps")?;
    let mut fields = Vec::with_capacity(options.len());
    for (k, v) in options.iter() {
        let value: String = dumps
            .call((&v,), Some(&kw))
            .map_err(|_| {
                ConfigError::new_err(format!(
                    "{k}={} is not a plain value: give {k} a number, a string or a list of them",
                    v.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })?
            .extract()?;
        let key: String = dumps.call1((k.str()?,))?.extract()?;
        fields.push(format!("{key}:{value}"));
    }
    let text = format!("{{{}}}", fields.join(","));
    let mut de = serde_json::Deserializer::from_str(&text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let what = e.inner().to_string();
        let what = what.split(" at line").next().unwrap_or_default();
        if what.contains("integer `-") && what.contains("expected u") {
            // a negative count: name the keyword and what it takes
            let got = what.split('`').nth(1).unwrap_or("it");
            return PyValueError::new_err(format!(
                "{} must be a whole number >= 0, not {got}",
                e.path()
            ));
        }
        PyTypeError::new_err(format!("{}: {what}", e.path()))
    })
}

/// A grid value: a number, never a bool (Python's `True` is an int 1, and
/// `kp=[True, False]` is a mistake, not kp 1 and 0).
fn number(x: &Bound<'_, PyAny>) -> Option<f64> {
    if x.is_instance_of::<PyBool>() {
        return None;
    }
    x.extract::<f64>().ok()
}

/// A grid as Python gives it: a dict of axis -> values (numbers, or text
/// parsed as the CLI parses it), a list of `AXIS=VALUES` strings, or one.
pub(crate) fn grid_from(
    grid: Option<&Bound<'_, PyAny>>,
    preset: Option<String>,
) -> PyResult<GridInput> {
    let grid = match (grid, preset) {
        (Some(g), _) if g.is_none() => None,
        (g, None) => g,
        (None, Some(p)) => return Ok(GridInput::Preset(p)),
        (Some(_), Some(_)) => {
            return Err(GridError::new_err(
                "give a grid or a preset, not both: drop one of them",
            ));
        }
    };
    let Some(grid) = grid else {
        return Ok(GridInput::None);
    };
    if let Ok(text) = grid.extract::<String>() {
        return Ok(GridInput::Specs(vec![text]));
    }
    // a list of cells: [{"kp": 10, "kd": 0.5}, ...] (a "name" key names one)
    if let Ok(cells) = grid.extract::<Vec<Bound<'_, PyDict>>>()
        && !cells.is_empty()
    {
        return cells_from(&cells);
    }
    if let Ok(dict) = grid.cast::<PyDict>() {
        let mut axes = Vec::with_capacity(dict.len());
        for (name, values) in dict.iter() {
            let name: String = name.str()?.to_string();
            let input = axis_from(&name, &values)?;
            axes.push((name, input));
        }
        return Ok(GridInput::Axes(axes));
    }
    let specs: Vec<String> = grid.extract().map_err(|_| {
        GridError::new_err(
            "grid must be a dict {axis: values}, a list of 'AXIS=VALUES' strings, or one such string",
        )
    })?;
    Ok(GridInput::Specs(specs))
}

/// Cells one by one, each a dict with the first cell's axes (and maybe a
/// "name"): not a product.
fn cells_from(cells: &[Bound<'_, PyDict>]) -> PyResult<GridInput> {
    let mut axes: Vec<String> = Vec::new();
    for (k, _) in cells[0].iter() {
        let k: String = k.str()?.to_string();
        if k != "name" {
            axes.push(k);
        }
    }
    let mut rows = Vec::with_capacity(cells.len());
    let mut names = Vec::new();
    for (i, c) in cells.iter().enumerate() {
        let mut row = Vec::with_capacity(axes.len());
        for a in &axes {
            let v = c.get_item(a)?.ok_or_else(|| {
                GridError::new_err(format!(
                    "cell {i} has no '{a}': give every cell the same axes"
                ))
            })?;
            row.push(
                number(&v).ok_or_else(|| {
                    GridError::new_err(format!("cell {i}'s '{a}' is not a number"))
                })?,
            );
        }
        if c.len() != axes.len() + usize::from(c.contains("name")?) {
            return Err(GridError::new_err(format!(
                "cell {i} has other axes than the first cell ({}): give every cell the same axes",
                axes.join(", ")
            )));
        }
        if let Some(n) = c.get_item("name")? {
            names.push(n.str()?.to_string());
        }
        rows.push(row);
    }
    Ok(GridInput::Cells { axes, rows, names })
}

/// One axis of a dict grid: text, names, one number or a list of numbers.
fn axis_from(name: &str, values: &Bound<'_, PyAny>) -> PyResult<AxisInput> {
    if let Ok(text) = values.extract::<String>() {
        return Ok(AxisInput::Text(text));
    }
    if let Ok(names) = values.extract::<Vec<String>>() {
        // names (the variant axis), parsed as the CLI parses them
        return Ok(AxisInput::Text(names.join(",")));
    }
    if let Some(v) = number(values) {
        return Ok(AxisInput::Values(vec![v]));
    }
    let items: Vec<Bound<'_, PyAny>> = values
        .try_iter()
        .and_then(|it| it.collect::<PyResult<_>>())
        .map_err(|_| {
            GridError::new_err(format!(
                "grid axis '{name}' has values of type {}: give numbers, a list of numbers, or text like '10,30' or '1:120:16:log'",
                values.get_type().name().map(|n| n.to_string()).unwrap_or_default()
            ))
        })?;
    let v = items
        .iter()
        .map(|x| {
            number(x).ok_or_else(|| {
                GridError::new_err(format!(
                    "grid axis '{name}' has a non-numeric value {}: use numbers like 10 or 0.5",
                    x.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })
        })
        .collect::<PyResult<Vec<f64>>>()?;
    Ok(AxisInput::Values(v))
}

/// A run directory argument: `str` or `os.PathLike`, not empty.
pub(crate) fn out_from(out: Option<&Bound<'_, PyAny>>) -> PyResult<Option<PathBuf>> {
    let Some(out) = out.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let is_path = out.is_instance_of::<PyString>() || out.hasattr("__fspath__").unwrap_or(false);
    let path: Option<PathBuf> = if is_path { out.extract().ok() } else { None };
    match path {
        Some(p) if p.as_os_str().is_empty() => Err(OutputError::new_err(
            "out is an empty path: give a directory name, e.g. out='runs/my-sweep'",
        )),
        Some(p) => Ok(Some(p)),
        None => Err(PyTypeError::new_err(format!(
            "out must be a str or os.PathLike, not {}",
            out.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))),
    }
}

/// A command's keywords taken from its `**options` one by one the way pyo3
/// takes declared arguments, not through [`spec_from`]'s JSON: the same
/// conversions, and the same errors (an unknown keyword; a wrong type,
/// noted "while processing 'NAME'").
pub(crate) struct Keywords<'a, 'py>(Option<&'a Bound<'py, PyDict>>);

impl<'a, 'py> Keywords<'a, 'py> {
    /// The keywords of `function`; the first one (in the call's order) not
    /// in `known` is refused, as pyo3 refuses it.
    pub(crate) fn of(
        function: &str,
        options: Option<&'a Bound<'py, PyDict>>,
        known: &[&str],
    ) -> PyResult<Self> {
        for key in options.iter().flat_map(|o| o.keys()) {
            let key = key.str()?.to_string_lossy().into_owned();
            if !known.contains(&key.as_str()) {
                return Err(PyTypeError::new_err(format!(
                    "{function}() got an unexpected keyword argument '{key}'"
                )));
            }
        }
        Ok(Keywords(options))
    }

    /// The keywords `own` of `options`, taken with [`get`](Self::get), and
    /// the others (None when there are none), left for [`spec_from`].
    pub(crate) fn split(
        options: Option<&'a Bound<'py, PyDict>>,
        own: &[&str],
    ) -> PyResult<(Self, Option<Bound<'py, PyDict>>)> {
        let Some(given) = options else {
            return Ok((Keywords(None), None));
        };
        let rest = given.copy()?;
        for k in own {
            if rest.contains(k)? {
                rest.del_item(k)?;
            }
        }
        Ok((Keywords(options), (!rest.is_empty()).then_some(rest)))
    }

    /// The keyword `name` as a `T`, or `default` when it is not given.
    pub(crate) fn get<T>(&self, name: &str, default: T) -> PyResult<T>
    where
        T: for<'b> FromPyObject<'b, 'py>,
    {
        match self.0.map(|o| o.get_item(name)).transpose()?.flatten() {
            Some(value) => argument(name, &value),
            None => Ok(default),
        }
    }
}

/// The argument `name` as a `T`; a failure carries pyo3's note naming it.
pub(crate) fn argument<'py, T>(name: &str, value: &Bound<'py, PyAny>) -> PyResult<T>
where
    T: for<'b> FromPyObject<'b, 'py>,
{
    value.extract::<T>().map_err(|e| {
        let e: PyErr = e.into();
        let _ = e
            .value(value.py())
            .call_method1("add_note", (format!("while processing '{name}'"),));
        e
    })
}

/// A command's own keywords, as a struct whose fields bear their names: the
/// list of them, and the struct as [`Keywords`] give it (what is not given
/// keeps the struct's `Default`). [`keywords!`] writes it from the fields.
pub(crate) trait Options: Sized {
    /// In the signature's order, the order they are taken and checked in.
    const KEYWORDS: &'static [&'static str];

    fn read(k: &Keywords<'_, '_>) -> PyResult<Self>;

    /// `{name: default, ...}`: the struct's `Default`, which the Python
    /// function's signature takes (`_native.kind_defaults`).
    fn defaults(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>>;

    /// `name=default, ...` as Python writes the defaults: what the
    /// command's `text_signature` shows.
    #[cfg(test)]
    fn shown() -> String;
}

/// `keywords!(Type { field, ... })`: [`Options`] for `Type`, its keywords
/// the fields named, in that order.
macro_rules! keywords {
    ($ty:ty { $($field:ident),+ $(,)? }) => {
        impl $crate::convert::Options for $ty {
            const KEYWORDS: &'static [&'static str] = &[$(stringify!($field)),+];

            fn read(k: &$crate::convert::Keywords<'_, '_>) -> pyo3::PyResult<Self> {
                let d = <$ty as Default>::default();
                Ok(Self {
                    $($field: k.get(stringify!($field), d.$field)?),+
                })
            }

            fn defaults(py: pyo3::Python<'_>) -> pyo3::PyResult<pyo3::Bound<'_, pyo3::types::PyDict>> {
                use pyo3::types::PyDictMethods;
                let d = <$ty as Default>::default();
                let out = pyo3::types::PyDict::new(py);
                $(out.set_item(stringify!($field), d.$field)?;)+
                Ok(out)
            }

            #[cfg(test)]
            fn shown() -> String {
                let d = <$ty as Default>::default();
                let shown = [$(format!(
                    "{}={}",
                    stringify!($field),
                    $crate::convert::shown::Repr::repr(&d.$field)
                )),+];
                shown.join(", ")
            }
        }
    };
}
pub(crate) use keywords;

/// What a command's `text_signature` shows, as its tests check it.
#[cfg(test)]
pub(crate) mod shown {
    /// A default as Python's `repr()` writes it (a sequence as a tuple).
    pub(crate) trait Repr {
        fn repr(&self) -> String;
    }

    /// Panics unless `source` holds the `text_signature` `shown` as a string.
    pub(crate) fn assert_declares(source: &str, shown: &str) {
        assert!(
            source.contains(&format!("\"{shown}\"")),
            "the text_signature should read {shown}"
        );
    }

    impl Repr for f64 {
        fn repr(&self) -> String {
            format!("{self:?}")
        }
    }

    impl Repr for usize {
        fn repr(&self) -> String {
            self.to_string()
        }
    }

    impl Repr for i128 {
        fn repr(&self) -> String {
            self.to_string()
        }
    }

    impl Repr for bool {
        fn repr(&self) -> String {
            if *self { "True" } else { "False" }.into()
        }
    }

    impl Repr for String {
        fn repr(&self) -> String {
            format!("'{self}'")
        }
    }

    impl<T: Repr> Repr for Option<T> {
        fn repr(&self) -> String {
            self.as_ref().map_or("None".into(), Repr::repr)
        }
    }

    impl<T: Repr> Repr for [T] {
        fn repr(&self) -> String {
            let items: Vec<String> = self.iter().map(Repr::repr).collect();
            match items.as_slice() {
                [one] => format!("({one},)"),
                _ => format!("({})", items.join(", ")),
            }
        }
    }

    impl<T: Repr> Repr for Vec<T> {
        fn repr(&self) -> String {
            self.as_slice().repr()
        }
    }

    impl<T: Repr, const N: usize> Repr for [T; N] {
        fn repr(&self) -> String {
            self.as_slice().repr()
        }
    }
}
