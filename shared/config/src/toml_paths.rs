//! Dotted key paths into a parsed TOML document (`protocol.rest_s`,
//! `experiment[3].alpha`), the names every configuration error uses: the
//! numeric leaves of a document, and the value at a path. For tests and
//! tools that walk a configuration file's keys (e.g. setting each numeric
//! key to NaN in turn).

use toml::{Table, Value};

/// Every numeric leaf below `v`: its dotted path and whether it is an integer.
pub fn numeric_leaves(v: &Value) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    walk(v, "", &mut out);
    out
}

fn walk(v: &Value, path: &str, out: &mut Vec<(String, bool)>) {
    match v {
        Value::Integer(_) => out.push((path.to_string(), true)),
        Value::Float(_) => out.push((path.to_string(), false)),
        Value::Table(t) => {
            for (k, v) in t {
                let p = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                walk(v, &p, out);
            }
        }
        Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                walk(v, &format!("{path}[{i}]"), out);
            }
        }
        _ => {}
    }
}

/// The value at a dotted path (with `[i]` indices), mutably; `None` when the
/// path does not name one.
pub fn leaf_mut<'a>(doc: &'a mut Table, path: &str) -> Option<&'a mut Value> {
    let mut parts = path.split('.');
    let (name, indices) = split_indices(parts.next()?)?;
    let mut v = doc.get_mut(name)?;
    for i in indices {
        v = v.as_array_mut()?.get_mut(i)?;
    }
    for part in parts {
        let (name, indices) = split_indices(part)?;
        v = v.as_table_mut()?.get_mut(name)?;
        for i in indices {
            v = v.as_array_mut()?.get_mut(i)?;
        }
    }
    Some(v)
}

fn split_indices(part: &str) -> Option<(&str, Vec<usize>)> {
    match part.find('[') {
        None => Some((part, vec![])),
        Some(at) => Some((
            &part[..at],
            part[at..]
                .split(['[', ']'])
                .filter(|s| !s.is_empty())
                .map(|s| s.parse().ok())
                .collect::<Option<Vec<usize>>>()?,
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_are_named_as_errors_name_them() {
        let mut doc: Table =
            toml::from_str("a = 1\n[b]\nc = 2.5\nd = [1, [2.0, 3]]\ne = \"x\"\n").unwrap();
        let leaves = numeric_leaves(&Value::Table(doc.clone()));
        let names: Vec<&str> = leaves.iter().map(|(p, _)| p.as_str()).collect();
        assert_eq!(names, ["a", "b.c", "b.d[0]", "b.d[1][0]", "b.d[1][1]"]);
        assert!(leaves[0].1);
        assert!(!leaves[1].1);
        assert_eq!(
            leaf_mut(&mut doc, "b.d[1][1]").cloned(),
            Some(Value::Integer(3))
        );
        *leaf_mut(&mut doc, "b.c").unwrap() = Value::Float(f64::NAN);
        assert!(doc["b"]["c"].as_float().unwrap().is_nan());
        assert!(leaf_mut(&mut doc, "b.z").is_none());
        assert!(leaf_mut(&mut doc, "b.d[7]").is_none());
    }
}
