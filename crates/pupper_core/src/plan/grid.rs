//! Gain grids: `--grid AXIS=VALUES` specs, their cartesian product, presets.
//!
//! A value list is `10,30,60,120`, a linear range `start:stop:count`, or a
//! log range `start:stop:count:log`. Axes keep the order they were given; the
//! last axis varies fastest, so cell order is the reading order of the specs.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
pub use crate::plan::axis::Axis;
use crate::robot::variant::VARIANTS;

/// One axis with its values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisValues {
    pub axis: Axis,
    pub values: Vec<f64>,
}

impl AxisValues {
    /// Parses `AXIS=VALUES`.
    pub fn parse(spec: &str) -> Result<AxisValues> {
        let Some((name, values)) = spec.split_once('=') else {
            return Err(Error::Grid(format!(
                "grid spec '{spec}' has no '=': write it as AXIS=VALUES, e.g. kp=10,30,60"
            )));
        };
        let axis = Axis::parse(name)?;
        let values = parse_values(axis, values)?;
        AxisValues::new(axis, values)
    }

    pub fn new(axis: Axis, values: Vec<f64>) -> Result<AxisValues> {
        if values.is_empty() {
            return Err(Error::Grid(format!(
                "grid axis '{axis}' has no values: give at least one, e.g. {axis}=1,2"
            )));
        }
        for &v in &values {
            if !v.is_finite() {
                return Err(Error::Grid(format!(
                    "grid axis '{axis}' has a non-finite value ({v}): use finite numbers"
                )));
            }
            axis.check(v)?;
        }
        // a value given twice would make two cells with one id; a set keeps
        // the check linear (a 20,001-value axis took 40 s to refuse)
        let mut seen = std::collections::HashSet::with_capacity(values.len());
        for &v in &values {
            let text = axis.text(v);
            if !seen.insert(text) {
                return Err(Error::Grid(format!(
                    "grid axis '{axis}' has the value {} twice: give each value once",
                    axis.text(v)
                )));
            }
        }
        Ok(AxisValues { axis, values })
    }
}

fn parse_number(axis: Axis, text: &str) -> Result<f64> {
    let t = text.trim();
    if t.is_empty() {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' has an empty value: remove the stray ',' or ':'"
        )));
    }
    let v: f64 = t.parse().map_err(|_| {
        Error::Grid(format!(
            "grid axis '{axis}' has a non-numeric value '{t}': use numbers like 10, 0.5 or 1e-3"
        ))
    })?;
    if !v.is_finite() {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' has a non-finite value '{t}': use finite numbers"
        )));
    }
    Ok(v)
}

/// Parses the right-hand side of `AXIS=VALUES`.
pub fn parse_values(axis: Axis, text: &str) -> Result<Vec<f64>> {
    let text = text.trim();
    if axis == Axis::Variant {
        return text
            .split(',')
            .map(|name| {
                let name = name.trim();
                VARIANTS
                    .iter()
                    .position(|b| b.name == name)
                    .map(|i| i as f64)
                    .ok_or_else(|| {
                        let names: Vec<&str> = VARIANTS.iter().map(|b| b.name).collect();
                        Error::Grid(format!(
                            "grid axis 'variant' has an unknown body '{name}': use names from {}",
                            names.join(", ")
                        ))
                    })
            })
            .collect();
    }
    if text.is_empty() {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' has no values: give a list (1,2,3) or a range (start:stop:count)"
        )));
    }
    if !text.contains(':') {
        return text.split(',').map(|t| parse_number(axis, t)).collect();
    }
    let parts: Vec<&str> = text.split(':').collect();
    let log = match parts.len() {
        3 => false,
        4 if parts[3].trim().eq_ignore_ascii_case("log") => true,
        _ => {
            return Err(Error::Grid(format!(
                "grid axis '{axis}' has a malformed range '{text}': write start:stop:count or start:stop:count:log"
            )));
        }
    };
    let start = parse_number(axis, parts[0])?;
    let stop = parse_number(axis, parts[1])?;
    let count: usize = parts[2].trim().parse().map_err(|_| {
        Error::Grid(format!(
            "grid axis '{axis}' range count '{}' is not a whole number: write start:stop:count, e.g. 10:120:12",
            parts[2].trim()
        ))
    })?;
    if count == 0 {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' range '{text}' has count 0: the count must be at least 1"
        )));
    }
    // the values are made before the grid's size is checked: a count past
    // any cell limit is refused before it is allocated
    if count > MAX_AXIS_VALUES {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' range '{text}' asks for {count} values, over the {MAX_AXIS_VALUES} an axis may have: lower the count"
        )));
    }
    if log && (start <= 0.0 || stop <= 0.0) {
        return Err(Error::Grid(format!(
            "grid axis '{axis}' log range '{text}' reaches zero or below: both ends must be > 0"
        )));
    }
    Ok(range(start, stop, count, log))
}

/// `count` points from `start` to `stop` inclusive, evenly spaced (in log
/// space for `log`). The ends are exact.
pub fn range(start: f64, stop: f64, count: usize, log: bool) -> Vec<f64> {
    if count == 1 {
        return vec![start];
    }
    let n = (count - 1) as f64;
    (0..count)
        .map(|i| {
            if i == 0 {
                start
            } else if i == count - 1 {
                stop
            } else if log {
                let (a, b) = (start.ln(), stop.ln());
                (a + (b - a) * i as f64 / n).exp()
            } else {
                start + (stop - start) * i as f64 / n
            }
        })
        .collect()
}

/// A grid of named axes; its cells are the cartesian product.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Grid {
    pub axes: Vec<AxisValues>,
    /// Optional names per cell (presets), in cell order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub names: Vec<String>,
    /// Explicit cells instead of a product (presets whose cells are not a product).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub explicit: Vec<Vec<f64>>,
}

/// One setting of every grid axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// Position in grid order.
    pub index: usize,
    /// Stable id derived from the values, e.g. `kp30_kd0.5`.
    pub id: String,
    /// Preset name, or empty.
    pub name: String,
    pub values: Vec<(Axis, f64)>,
}

impl Cell {
    pub fn get(&self, axis: Axis) -> Option<f64> {
        self.values
            .iter()
            .find(|(a, _)| *a == axis)
            .map(|(_, v)| *v)
    }
}

/// Default limit on grid size, to catch a typo that would run for days.
pub const DEFAULT_MAX_CELLS: usize = 100_000;

/// The most values one axis may list: ten times the default cell limit,
/// so a range is refused before its values are allocated.
pub const MAX_AXIS_VALUES: usize = 1_000_000;

impl Grid {
    /// Builds a grid from `AXIS=VALUES` specs, rejecting duplicate axes.
    pub fn parse<S: AsRef<str>>(specs: &[S]) -> Result<Grid> {
        let axes = specs
            .iter()
            .map(|s| AxisValues::parse(s.as_ref()))
            .collect::<Result<Vec<_>>>()?;
        Grid::from_axes(axes)
    }

    pub fn from_axes(axes: Vec<AxisValues>) -> Result<Grid> {
        for (i, a) in axes.iter().enumerate() {
            if axes[..i].iter().any(|b| b.axis == a.axis) {
                return Err(Error::Grid(format!(
                    "grid axis '{}' is given twice: merge the values into one --grid {}=...",
                    a.axis, a.axis
                )));
            }
        }
        Ok(Grid {
            axes,
            names: Vec::new(),
            explicit: Vec::new(),
        })
    }

    /// Cells given one by one (not a product): each row holds a value per
    /// axis, in `axes` order; `names` (empty, or one per row) name them.
    /// What a search asks for, a generation at a time.
    pub fn explicit(axes: &[String], rows: Vec<Vec<f64>>, names: Vec<String>) -> Result<Grid> {
        let parsed = axes
            .iter()
            .map(|a| Axis::parse(a))
            .collect::<Result<Vec<_>>>()?;
        if rows.is_empty() {
            return Err(Error::Grid("no cells given: give at least one".into()));
        }
        if !names.is_empty() && names.len() != rows.len() {
            return Err(Error::Grid(format!(
                "{} names for {} cells: give one name per cell, or none",
                names.len(),
                rows.len()
            )));
        }
        let mut columns = vec![Vec::with_capacity(rows.len()); parsed.len()];
        for (i, row) in rows.iter().enumerate() {
            if row.len() != parsed.len() {
                return Err(Error::Grid(format!(
                    "cell {i} has {} values for {} axes ({}): give one value per axis",
                    row.len(),
                    parsed.len(),
                    axes.join(", ")
                )));
            }
            for (k, (&axis, &v)) in parsed.iter().zip(row).enumerate() {
                if !v.is_finite() {
                    return Err(Error::Grid(format!(
                        "cell {i} has {axis} = {v}: give finite numbers"
                    )));
                }
                axis.check(v)?;
                columns[k].push(v);
            }
        }
        let axes = parsed
            .into_iter()
            .zip(columns)
            .map(|(axis, values)| AxisValues { axis, values })
            .collect();
        Ok(Grid {
            axes,
            names,
            explicit: rows,
        })
    }

    /// Named presets: `chapter-4.6` is the chapter's four servo cases.
    pub fn preset(name: &str) -> Result<Grid> {
        match name {
            "chapter-4.6" | "chapter" => Ok(Grid {
                axes: vec![
                    AxisValues {
                        axis: Axis::Kp,
                        values: vec![1.0, 5.0, 30.0, 5.0],
                    },
                    AxisValues {
                        axis: Axis::Kd,
                        values: vec![0.05, 0.1, 0.1, 0.0],
                    },
                ],
                names: ["soft", "default", "stiff", "underD"]
                    .map(String::from)
                    .to_vec(),
                explicit: vec![
                    vec![1.0, 0.05],
                    vec![5.0, 0.1],
                    vec![30.0, 0.1],
                    vec![5.0, 0.0],
                ],
            }),
            "lab-grid" => Grid::parse(&["kp=10,30,60,120", "kd=0.5,1,2,5"]),
            // the old name read as the lab itself, which also sets the mode,
            // the disturbance and the bodies
            "lab" => Err(Error::Grid(
                "preset 'lab' is now 'lab-grid': it is only the lab's 4x4 Kp x Kd grid; for the lab itself (torque mode, the sine, every body) run `pupper lab`".into(),
            )),
            _ => Err(Error::Grid(format!(
                "unknown preset '{name}': known presets are {}",
                PRESETS.join(", ")
            ))),
        }
    }

    pub fn len(&self) -> usize {
        if !self.explicit.is_empty() {
            return self.explicit.len();
        }
        if self.axes.is_empty() {
            return 1;
        }
        self.axes
            .iter()
            .map(|a| a.values.len())
            .try_fold(1usize, |acc, n| acc.checked_mul(n))
            .unwrap_or(usize::MAX)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn check_size(&self, max_cells: usize) -> Result<()> {
        let n = self.len();
        if n > max_cells {
            let shown = if n == usize::MAX {
                "more than 2^64".to_string()
            } else {
                n.to_string()
            };
            return Err(Error::Grid(format!(
                "the grid would make {shown} cells, over the limit of {max_cells}: use fewer values or raise --max-cells"
            )));
        }
        Ok(())
    }

    pub fn has_axis(&self, axis: Axis) -> bool {
        self.axes.iter().any(|a| a.axis == axis)
    }

    /// The cells in grid order (last axis fastest).
    pub fn cells(&self) -> Vec<Cell> {
        let axes: Vec<Axis> = self.axes.iter().map(|a| a.axis).collect();
        let rows: Vec<Vec<f64>> = if !self.explicit.is_empty() {
            self.explicit.clone()
        } else {
            let mut rows = vec![Vec::new()];
            for a in &self.axes {
                rows = rows
                    .into_iter()
                    .flat_map(|row| {
                        a.values.iter().map(move |v| {
                            let mut r = row.clone();
                            r.push(*v);
                            r
                        })
                    })
                    .collect();
            }
            rows
        };
        rows.into_iter()
            .enumerate()
            .map(|(index, row)| {
                let values: Vec<(Axis, f64)> = axes.iter().copied().zip(row).collect();
                Cell {
                    index,
                    id: cell_id(&values),
                    name: self.names.get(index).cloned().unwrap_or_default(),
                    values,
                }
            })
            .collect()
    }
}

pub const PRESETS: [&str; 2] = ["chapter-4.6", "lab-grid"];

/// `kp30_kd0.5`: short, stable, file-name safe.
pub fn cell_id(values: &[(Axis, f64)]) -> String {
    if values.is_empty() {
        return "base".to_string();
    }
    values
        .iter()
        .map(|(a, v)| format!("{}{}", a.tag(), a.text(*v)))
        .collect::<Vec<_>>()
        .join("_")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_given_twice_is_refused() {
        let e = Grid::parse(&["kp=10,30,10"]).unwrap_err().to_string();
        assert!(e.contains("value 10 twice"), "{e}");
        let e = AxisValues::new(Axis::Kd, vec![0.5, 0.5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("0.5 twice"), "{e}");
        assert!(Grid::parse(&["kp=10,30"]).is_ok());
    }

    #[test]
    fn list_values() {
        let a = AxisValues::parse("kp=10,30, 60,120").unwrap();
        assert_eq!(a.axis, Axis::Kp);
        assert_eq!(a.values, vec![10.0, 30.0, 60.0, 120.0]);
    }

    #[test]
    fn linear_range_has_exact_ends() {
        let a = AxisValues::parse("kp=10:120:12").unwrap();
        assert_eq!(a.values.len(), 12);
        assert_eq!(a.values[0], 10.0);
        assert_eq!(a.values[11], 120.0);
        assert_eq!(a.values[1], 20.0);
    }

    #[test]
    fn log_range() {
        let a = AxisValues::parse("kd=1:100:5:log").unwrap();
        let want = [1.0, 3.1622776601683795, 10.0, 31.622776601683793, 100.0];
        for (g, w) in a.values.iter().zip(want) {
            assert!((g - w).abs() < 1e-12 * w, "{g} vs {w}");
        }
    }

    #[test]
    fn single_point_range() {
        assert_eq!(AxisValues::parse("kp=7:9:1").unwrap().values, vec![7.0]);
    }

    #[test]
    fn product_order_and_ids() {
        let g = Grid::parse(&["kp=10,30", "kd=0.5,1,2"]).unwrap();
        assert_eq!(g.len(), 6);
        let cells = g.cells();
        assert_eq!(cells[0].id, "kp10_kd0.5");
        assert_eq!(cells[1].id, "kp10_kd1");
        assert_eq!(cells[3].id, "kp30_kd0.5");
        assert_eq!(cells[5].get(Axis::Kd), Some(2.0));
        assert_eq!(cells[5].index, 5);
    }

    #[test]
    fn preset_names() {
        let g = Grid::preset("chapter-4.6").unwrap();
        let cells = g.cells();
        assert_eq!(cells.len(), 4);
        assert_eq!(cells[0].name, "soft");
        assert_eq!(cells[3].name, "underD");
        assert_eq!(cells[3].get(Axis::Kd), Some(0.0));
        assert_eq!(cells[2].id, "kp30_kd0.1");
    }

    fn err(spec: &str) -> String {
        AxisValues::parse(spec).unwrap_err().to_string()
    }

    #[test]
    fn bad_specs_name_the_problem() {
        assert!(err("kpp=1").contains("did you mean 'kp'?"));
        assert!(
            err("kq=1").contains("did you mean 'kp' or 'kd'?"),
            "{}",
            err("kq=1")
        );
        assert!(err("timestpe=1").contains("'timestep'"));
        assert!(err("kp").contains("no '='"));
        assert!(err("kp=").contains("no values"));
        assert!(err("kp=1,,2").contains("empty value"));
        assert!(err("kp=abc").contains("non-numeric"));
        assert!(err("kp=nan").contains("non-finite"));
        assert!(err("kp=inf").contains("non-finite"));
        assert!(err("kp=1:2:0").contains("count 0"));
        assert!(err("kp=0:10:3:log").contains("log range"));
        assert!(err("kp=-1").contains(">= 0"));
        assert!(err("max_torque=0").contains("> 0"));
        assert!(err("kp=1:2").contains("malformed range"));
        assert!(err("kp=1:2:x").contains("whole number"));
    }

    #[test]
    fn duplicate_axes_rejected() {
        let e = Grid::parse(&["kp=1", "kp=2"]).unwrap_err().to_string();
        assert!(e.contains("given twice"));
    }

    #[test]
    fn size_limit() {
        let g = Grid::parse(&["kp=1:2:1000", "kd=1:2:1000"]).unwrap();
        let e = g.check_size(1000).unwrap_err().to_string();
        assert!(e.contains("1000000 cells"), "{e}");
        assert!(g.check_size(DEFAULT_MAX_CELLS * 10).is_ok());
    }

    #[test]
    fn a_huge_range_is_refused_before_its_values_exist() {
        // 10^12 values would be 8 TB: refused from the count alone
        let e = err("kp=0:1:1000000000000");
        assert!(
            e.contains("1000000000000 values") && e.contains("lower the count"),
            "{e}"
        );
        assert_eq!(
            parse_values(Axis::Kp, &format!("0:1:{MAX_AXIS_VALUES}"))
                .unwrap()
                .len(),
            MAX_AXIS_VALUES
        );
    }

    #[test]
    fn a_long_axis_finds_its_repeated_value() {
        let mut values: Vec<f64> = (0..20_001).map(f64::from).collect();
        assert!(AxisValues::new(Axis::Kp, values.clone()).is_ok());
        values.push(7.0);
        let e = AxisValues::new(Axis::Kp, values).unwrap_err().to_string();
        assert!(e.contains("the value 7 twice"), "{e}");
    }

    #[test]
    fn empty_grid_is_one_cell() {
        let g = Grid::parse::<&str>(&[]).unwrap();
        assert_eq!(g.len(), 1);
        assert_eq!(g.cells()[0].id, "base");
    }
}
