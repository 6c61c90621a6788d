//! Task overrides: a task file's TOML with some values replaced, addressed by path
//! (`input.weight`, `waypoint[0].desired.base_position[0]`), for sweeps and scripts that
//! vary one number of a task without writing a file per variant.
//!
//! A path must lead through tables and arrays that exist; its last key may be new in an
//! existing table (the task's own parsing then refuses a field it does not know). An index
//! past the end of an array, or a key through a value that is not a table, is an error that
//! names the path.

use super::{TaskError, TaskSpec};

/// One step of an override path.
#[derive(Debug, PartialEq)]
enum Step<'p> {
    Key(&'p str),
    Index(usize),
}

/// Splits `a.b[2].c` into its steps.
fn steps(path: &str) -> Result<Vec<Step<'_>>, String> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = part.find('[').map_or((part, ""), |i| (&part[..i], &part[i..]));
        if key.is_empty() {
            return Err("expected a key before each '.' and '['".into());
        }
        out.push(Step::Key(key));
        while !rest.is_empty() {
            let close = rest.find(']').filter(|_| rest.starts_with('[')).ok_or("expected [index]")?;
            let index = rest[1..close].parse::<usize>().map_err(|_| format!("expected a whole-number index, got [{}]", &rest[1..close]))?;
            out.push(Step::Index(index));
            rest = &rest[close + 1..];
        }
    }
    Ok(out)
}

/// Sets `value` at `path` in `table`.
fn set(table: &mut toml::Table, path: &str, value: toml::Value) -> Result<(), String> {
    let steps = steps(path)?;
    let (last, through) = steps.split_last().ok_or("empty path")?;
    let Some(Step::Key(first)) = through.first().or(Some(last)) else { return Err("a path starts with a key".into()) };
    if through.is_empty() {
        table.insert(first.to_string(), value);
        return Ok(());
    }
    let mut node = table.get_mut(*first).ok_or_else(|| format!("the task has no `{first}`"))?;
    for step in &through[1..] {
        node = match step {
            Step::Key(k) => node.as_table_mut().ok_or_else(|| format!("`{k}`: its parent is not a table"))?.get_mut(*k).ok_or_else(|| format!("the task has no `{k}` there"))?,
            Step::Index(i) => {
                let array = node.as_array_mut().ok_or_else(|| format!("[{i}]: not an array"))?;
                let n = array.len();
                array.get_mut(*i).ok_or_else(|| format!("[{i}]: the array has {n} entries"))?
            }
        };
    }
    match last {
        Step::Key(k) => {
            node.as_table_mut().ok_or_else(|| format!("`{k}`: its parent is not a table"))?.insert(k.to_string(), value);
        }
        Step::Index(i) => {
            let array = node.as_array_mut().ok_or_else(|| format!("[{i}]: not an array"))?;
            let n = array.len();
            *array.get_mut(*i).ok_or_else(|| format!("[{i}]: the array has {n} entries"))? = value;
        }
    }
    Ok(())
}

impl TaskSpec {
    /// Parses a task's TOML `text` with `overrides` applied, each `(path, value)`; errors
    /// name `origin` and the path.
    ///
    /// ```
    /// use legwork::ocp::{TaskSpec, EMBEDDED_TASKS};
    /// let text = EMBEDDED_TASKS.iter().find(|(n, _)| *n == "gallop").unwrap().1;
    /// let overrides = [("input.weight".to_string(), toml::Value::Float(0.1)),
    ///                  ("waypoint[0].desired.base_position[0]".to_string(), toml::Value::Float(1.5))];
    /// let spec = TaskSpec::from_toml_with_overrides(text, "embedded task gallop", &overrides).unwrap();
    /// assert_eq!(spec.input.weight, 0.1);
    /// assert!(TaskSpec::from_toml_with_overrides(text, "gallop", &[("waypoint[3].time".into(), toml::Value::Float(1.0))]).is_err());
    /// ```
    pub fn from_toml_with_overrides(text: &str, origin: &str, overrides: &[(String, toml::Value)]) -> Result<Self, TaskError> {
        if overrides.is_empty() {
            return Self::from_toml(text, origin);
        }
        let mut table: toml::Table = toml::from_str(text).map_err(|e| TaskError::Parse { origin: origin.into(), message: e.to_string() })?;
        for (path, value) in overrides {
            set(&mut table, path, value.clone()).map_err(|problem| TaskError::Invalid { origin: format!("{origin} (overrides)"), field: path.clone(), problem })?;
        }
        let text = toml::to_string(&table).map_err(|e| TaskError::Parse { origin: format!("{origin} (overrides)"), message: e.to_string() })?;
        Self::from_toml(&text, &format!("{origin} (overrides)"))
    }

    /// The TOML text of a task argument and where it came from (for messages): a `.toml`
    /// file (or any file of that name: a folder named like an embedded task, `out/gallop`,
    /// is not one), else an embedded task's name.
    pub fn text_of(task: &str) -> Result<(String, String), TaskError> {
        let path = std::path::Path::new(task);
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")) || path.is_file() {
            return Ok((super::task::read_task_file(path)?, task.to_string()));
        }
        Ok((super::task::embedded_text(task)?.to_string(), format!("embedded task {task}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_split_into_keys_and_indices() {
        assert_eq!(steps("a.b[2][1].c").unwrap(), vec![Step::Key("a"), Step::Key("b"), Step::Index(2), Step::Index(1), Step::Key("c")]);
        assert!(steps("a..b").is_err());
        assert!(steps("a[x]").is_err());
        assert!(steps("a[1").is_err());
    }

    #[test]
    fn an_override_replaces_one_value_and_a_wrong_path_is_named() {
        let mut t: toml::Table = toml::from_str("x = 1\n[input]\nweight = 0.01\n[[waypoint]]\ntime = 3.0\ndesired = { base_position = [2.0, 0.0] }\n").unwrap();
        set(&mut t, "input.weight", toml::Value::Float(0.5)).unwrap();
        set(&mut t, "waypoint[0].desired.base_position[0]", toml::Value::Float(1.25)).unwrap();
        assert_eq!(t["input"]["weight"].as_float(), Some(0.5));
        assert_eq!(t["waypoint"][0]["desired"]["base_position"][0].as_float(), Some(1.25));
        assert!(set(&mut t, "waypoint[1].time", toml::Value::Float(1.0)).unwrap_err().contains("1 entries"));
        assert!(set(&mut t, "nothing.here", toml::Value::Float(1.0)).unwrap_err().contains("no `nothing`"));
        assert!(set(&mut t, "x.y", toml::Value::Float(1.0)).unwrap_err().contains("not a table"));
    }
}
