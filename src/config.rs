//! The TOML configuration: label names, the outside label, the priority of
//! labels at critical elements, separation constraints, remeshing options.
//!
//! ```toml
//! outside = "background"       # label of everything outside the volume
//! priority = ["myocardium"]    # wins at critical edges/vertices, first listed first
//!
//! [labels]                     # label value = name
//! 0 = "background"
//! 1 = "lv_blood"
//! 2 = "rv_blood"
//! 3 = "myocardium"
//!
//! [[separate]]                 # these labels must never touch ...
//! labels = ["lv_blood", "rv_blood"]
//! by = "myocardium"            # ... a layer of this label goes between them
//!
//! [remesh]
//! target_edge = 2.0            # mm: the largest edge, where structures leave room
//! min_edge = 0.5               # mm: the smallest, where label regions are thin
//! ```
//!
//! Parsing ([`Config::from_toml_str`]) checks the syntax and the keys: unknown keys
//! and malformed entries are errors that name the key. Resolving against a volume
//! ([`Config::resolve`]) checks the names: unknown names, a separator inside its
//! own group, a group of fewer than two labels, a pair constrained twice with
//! different separators and constraints that undo each other are errors; a label
//! that does not occur in the volume is a warning.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::remesh::RemeshParams;
use crate::volume::{LabelId, LabelVolume};

/// A reference to a label: its value, or its name from `[labels]`.
#[derive(Clone, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(untagged)]
pub enum LabelRef {
    Value(i64),
    Name(String),
}

impl std::fmt::Display for LabelRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LabelRef::Value(v) => write!(f, "{v}"),
            LabelRef::Name(n) => write!(f, "\"{n}\""),
        }
    }
}

/// "These labels must never share a face; put `by` between them."
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Separation {
    pub labels: Vec<LabelRef>,
    pub by: LabelRef,
}

/// Options of the remeshing stage (`[remesh]`); `None` means the default.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct RemeshOptions {
    /// Remesh at all (default true).
    pub enabled: Option<bool>,
    /// Largest target edge length in mm (default: twice the mean voxel spacing).
    pub target_edge: Option<f64>,
    /// Smallest target edge length in mm, where label regions are thin
    /// (default: half the smallest voxel spacing).
    pub min_edge: Option<f64>,
    /// Smoothing iterations (default 10).
    pub smooth_iterations: Option<u32>,
    /// Largest displacement of a vertex by smoothing, in voxels per axis (default 0.5).
    pub max_displacement: Option<f64>,
    /// Remeshing iterations (default 5).
    pub iterations: Option<u32>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    outside: Option<LabelRef>,
    #[serde(default)]
    priority: Vec<LabelRef>,
    #[serde(default)]
    labels: BTreeMap<String, String>,
    #[serde(default)]
    separate: Vec<Separation>,
    #[serde(default)]
    remesh: RemeshOptions,
}

/// A parsed configuration (names not yet checked against a volume).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Config {
    /// Where it was read from (for messages); `None` for the built-in default.
    pub path: Option<PathBuf>,
    /// Label value → name, ascending by value.
    pub names: BTreeMap<i64, String>,
    pub outside: Option<LabelRef>,
    pub priority: Vec<LabelRef>,
    pub separate: Vec<Separation>,
    pub remesh: RemeshOptions,
}

impl Config {
    /// Reads and parses a TOML file.
    pub fn from_file(path: &Path) -> Result<Config> {
        crate::io::check_regular_file(path)?;
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_toml_str(&text, path)
    }

    /// Parses TOML text; `path` is used in messages only.
    ///
    /// ```
    /// use septa::config::Config;
    /// let c = Config::from_toml_str("[labels]\n1 = \"lv\"\n", "x.toml".as_ref()).unwrap();
    /// assert_eq!(c.name_of(1), Some("lv"));
    /// let e = Config::from_toml_str("[lables]\n", "x.toml".as_ref()).unwrap_err();
    /// assert!(e.to_string().contains("lables"));
    /// ```
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Config> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| {
            let key = match e.span() {
                Some(span) => {
                    let before = &text[..span.start.min(text.len())];
                    let line = before.matches('\n').count() + 1;
                    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                    match key_at(text, span.start) {
                        Some(k) => format!("line {line}, column {col} ({k})"),
                        None => format!("line {line}, column {col}"),
                    }
                }
                None => "config".to_string(),
            };
            Error::config(path, key, e.message().trim().to_string())
        })?;
        let mut names = BTreeMap::new();
        let mut seen_names: BTreeMap<String, i64> = BTreeMap::new();
        for (k, name) in raw.labels {
            let value: i64 = k.trim().parse().map_err(|_| {
                Error::config(
                    path,
                    format!("labels.\"{k}\""),
                    "label keys must be integer label values, e.g. `3 = \"myocardium\"`",
                )
            })?;
            if name.trim().is_empty() {
                return Err(Error::config(
                    path,
                    format!("labels.{k}"),
                    "a label name must not be empty",
                ));
            }
            if let Some(other) = seen_names.insert(name.clone(), value) {
                return Err(Error::config(
                    path,
                    format!("labels.{k}"),
                    format!("the name \"{name}\" is already used for label {other}"),
                ));
            }
            if names.insert(value, name).is_some() {
                return Err(Error::config(
                    path,
                    format!("labels.{k}"),
                    format!("label value {value} is named twice"),
                ));
            }
        }
        check_remesh_options(&raw.remesh, path)?;
        Ok(Config {
            path: Some(path.to_path_buf()),
            names,
            outside: raw.outside,
            priority: raw.priority,
            separate: raw.separate,
            remesh: raw.remesh,
        })
    }

    /// The name given to a label value, if any.
    pub fn name_of(&self, value: i64) -> Option<&str> {
        self.names.get(&value).map(String::as_str)
    }

    /// A name for a label value: its configured name, else `label<value>`.
    pub fn display_name(&self, value: i64) -> String {
        self.name_of(value)
            .map(str::to_string)
            .unwrap_or_else(|| format!("label{value}"))
    }

    fn path_for_messages(&self) -> PathBuf {
        self.path
            .clone()
            .unwrap_or_else(|| PathBuf::from("<config>"))
    }

    /// The value a reference stands for; `key` locates it in messages.
    pub fn value_of(&self, r: &LabelRef, key: &str) -> Result<i64> {
        match r {
            LabelRef::Value(v) => Ok(*v),
            LabelRef::Name(n) => {
                if let Some((v, _)) = self.names.iter().find(|(_, name)| *name == n) {
                    return Ok(*v);
                }
                if let Ok(v) = n.trim().parse::<i64>() {
                    return Ok(v);
                }
                let known: Vec<&str> = self.names.values().map(String::as_str).collect();
                Err(Error::config(
                    self.path_for_messages(),
                    key,
                    if known.is_empty() {
                        format!("unknown label name \"{n}\": [labels] names no labels")
                    } else {
                        format!("unknown label name \"{n}\" (known: {})", known.join(", "))
                    },
                ))
            }
        }
    }

    /// Checks the configuration against a volume and turns names into dense ids.
    ///
    /// Labels that the config introduces but the volume lacks (a separator, the
    /// outside label) are added to the volume's value table, so the returned
    /// volume may have more labels than the input.
    pub fn resolve(&self, volume: LabelVolume) -> Result<(LabelVolume, Resolved)> {
        let path = self.path_for_messages();
        let mut warnings = Vec::new();
        let occurs = |v: i64| volume.id_of(v).is_some();

        // Outside label.
        let outside_value = match &self.outside {
            Some(r) => self.value_of(r, "outside")?,
            None => volume.value(volume.most_frequent_border_label()),
        };
        if !occurs(outside_value) {
            let name = self
                .name_of(outside_value)
                .map(|n| format!(" ({n})"))
                .unwrap_or_default();
            warnings.push(format!(
                "outside: label {outside_value}{name} does not occur in the volume; it is added \
                 as a label around it (every label on the border gets a surface against it)"
            ));
        }

        // Separation constraints, as values first.
        let mut groups: Vec<(Vec<i64>, i64)> = Vec::new();
        let mut pair_by: BTreeMap<(i64, i64), (i64, usize)> = BTreeMap::new();
        for (ci, sep) in self.separate.iter().enumerate() {
            let by = self.value_of(&sep.by, &format!("separate[{ci}].by"))?;
            let mut members = Vec::new();
            for (li, r) in sep.labels.iter().enumerate() {
                let key = format!("separate[{ci}].labels[{li}]");
                let v = self.value_of(r, &key)?;
                if v == by {
                    return Err(Error::config(
                        &path,
                        key,
                        format!(
                            "label {} is also the separator `by` of this constraint",
                            self.display_name(v)
                        ),
                    ));
                }
                if members.contains(&v) {
                    return Err(Error::config(
                        &path,
                        key,
                        format!("label {} is listed twice", self.display_name(v)),
                    ));
                }
                members.push(v);
            }
            if members.len() < 2 {
                return Err(Error::config(
                    &path,
                    format!("separate[{ci}].labels"),
                    "a separation constraint needs at least two labels to keep apart",
                ));
            }
            for &v in &members {
                if !occurs(v) {
                    warnings.push(format!(
                        "separate[{ci}]: label {} does not occur in the volume; the constraint ignores it",
                        self.display_name(v)
                    ));
                }
            }
            if !occurs(by) {
                warnings.push(format!(
                    "separate[{ci}]: separator {} does not occur in the volume; it will be created where needed",
                    self.display_name(by)
                ));
            }
            for (i, &a) in members.iter().enumerate() {
                for &b in &members[i + 1..] {
                    let key = (a.min(b), a.max(b));
                    if let Some(&(other_by, other_ci)) = pair_by.get(&key) {
                        if other_by != by {
                            return Err(Error::config(
                                &path,
                                format!("separate[{ci}]"),
                                format!(
                                    "labels {} and {} are to be separated by {} here but by {} in separate[{other_ci}]",
                                    self.display_name(a),
                                    self.display_name(b),
                                    self.display_name(by),
                                    self.display_name(other_by)
                                ),
                            ));
                        }
                    } else {
                        pair_by.insert(key, (by, ci));
                    }
                }
            }
            groups.push((members, by));
        }
        // A separator put against a member must not itself be a constrained pair
        // with that member: fattening one constraint would break the other.
        for (ci, (members, by)) in groups.iter().enumerate() {
            for &m in members {
                let key = (m.min(*by), m.max(*by));
                if let Some(&(_, other_ci)) = pair_by.get(&key) {
                    return Err(Error::config(
                        &path,
                        format!("separate[{ci}]"),
                        format!(
                            "contradictory constraints: separating by {} puts it against {}, but separate[{other_ci}] forbids {} and {} to touch",
                            self.display_name(*by),
                            self.display_name(m),
                            self.display_name(*by),
                            self.display_name(m)
                        ),
                    ));
                }
            }
        }

        // Priority.
        let mut priority_values = Vec::new();
        for (i, r) in self.priority.iter().enumerate() {
            let v = self.value_of(r, &format!("priority[{i}]"))?;
            if priority_values.contains(&v) {
                return Err(Error::config(
                    &path,
                    format!("priority[{i}]"),
                    format!("label {} is listed twice", self.display_name(v)),
                ));
            }
            if !occurs(v) {
                warnings.push(format!(
                    "priority: label {} does not occur in the volume",
                    self.display_name(v)
                ));
            }
            priority_values.push(v);
        }

        // Named labels that are absent: only a note, names are allowed to cover
        // more labels than one volume has.
        let mut extra: Vec<i64> = vec![outside_value];
        extra.extend(groups.iter().map(|(_, by)| *by));
        let volume = with_extra_values(volume, &extra);
        let id = |v: i64| volume.id_of(v).expect("added above");

        let n = volume.label_count();
        let mut rank: Vec<u32> = (0..n as u32)
            .map(|i| i + priority_values.len() as u32)
            .collect();
        for (i, &v) in priority_values.iter().enumerate() {
            if let Some(lid) = volume.id_of(v) {
                rank[lid as usize] = i as u32;
            }
        }
        let separations = groups
            .iter()
            .map(|(members, by)| SeparationIds {
                labels: members.iter().filter_map(|&v| volume.id_of(v)).collect(),
                by: id(*by),
            })
            .collect();
        let resolved = Resolved {
            outside: id(outside_value),
            outside_from_config: self.outside.is_some(),
            rank,
            separations,
            warnings,
        };
        Ok((volume, resolved))
    }
}

/// The dotted key (`remesh.smooth_iterations`) of the `key = value` line
/// holding byte `at` of `text`, when the line is one: TOML's messages give
/// the position of a bad value but not always its key.
fn key_at(text: &str, at: usize) -> Option<String> {
    let at = at.min(text.len());
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next()?;
    let (key, _) = line.split_once('=')?;
    let key = key.trim();
    if key.is_empty() || key.starts_with('[') || key.starts_with('#') {
        return None;
    }
    let table = text[..start].lines().rev().find_map(|l| {
        let l = l.trim();
        (l.starts_with('[') && !l.starts_with("[["))
            .then(|| l.trim_matches(['[', ']']).trim().to_string())
    });
    Some(match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key.to_string(),
    })
}

/// Checks the `[remesh]` values on their own (the bounds of
/// [`RemeshParams::validate`]; those that depend on the volume are checked
/// when it is known); an error names the key.
fn check_remesh_options(o: &RemeshOptions, path: &Path) -> Result<()> {
    let d = RemeshParams::default();
    let p = RemeshParams {
        target_edge: o.target_edge.unwrap_or(d.target_edge),
        min_edge: o.min_edge,
        smooth_iterations: o.smooth_iterations.unwrap_or(d.smooth_iterations),
        max_displacement: o.max_displacement.unwrap_or(d.max_displacement),
        iterations: o.iterations.unwrap_or(d.iterations),
    };
    p.validate().map_err(|e| match e {
        Error::Parameter {
            name,
            value,
            problem,
        } => Error::config(
            path,
            format!("remesh.{name}"),
            format!("{value}: {problem}"),
        ),
        other => other,
    })
}

/// A volume whose value table also holds `extra` values (ids are remapped).
pub fn with_extra_values(volume: LabelVolume, extra: &[i64]) -> LabelVolume {
    use rayon::prelude::*;
    let missing: Vec<i64> = extra
        .iter()
        .copied()
        .filter(|&v| volume.id_of(v).is_none())
        .collect();
    if missing.is_empty() {
        return volume;
    }
    let mut values = volume.values().to_vec();
    values.extend(missing);
    values.sort_unstable();
    values.dedup();
    let remap: Vec<LabelId> = volume
        .values()
        .iter()
        .map(|v| values.binary_search(v).expect("kept") as LabelId)
        .collect();
    let ids = volume
        .ids()
        .par_iter()
        .map(|&i| remap[i as usize])
        .collect();
    LabelVolume::from_ids(volume.dims(), ids, values, *volume.geometry())
        .expect("remap keeps validity")
}

/// A separation constraint in dense ids.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SeparationIds {
    /// Labels that must not share a face (those that occur in the volume).
    pub labels: Vec<LabelId>,
    /// The label put between them.
    pub by: LabelId,
}

/// A configuration checked against one volume, in dense ids.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    /// Label of everything outside the volume.
    pub outside: LabelId,
    /// Whether `outside` was given by the config (else: most frequent border label).
    pub outside_from_config: bool,
    /// Dominance rank per dense id: at a critical element the critical label with
    /// the smallest rank is dominant (priority list first, then by value).
    pub rank: Vec<u32>,
    pub separations: Vec<SeparationIds>,
    /// Non-fatal findings to show the user.
    pub warnings: Vec<String>,
}

impl Resolved {
    /// Defaults for a volume without a config.
    pub fn defaults(volume: &LabelVolume) -> Resolved {
        Resolved {
            outside: volume.most_frequent_border_label(),
            outside_from_config: false,
            rank: (0..volume.label_count() as u32).collect(),
            separations: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Whether any separation constraint is active (switches fattening to 7³).
    pub fn has_constraints(&self) -> bool {
        self.separations.iter().any(|s| s.labels.len() >= 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Dims, Geometry};

    fn vol(values: &[i64]) -> LabelVolume {
        LabelVolume::from_values(
            Dims::new(values.len(), 1, 1).unwrap(),
            values,
            Geometry::identity(),
        )
        .unwrap()
    }

    const HEART: &str = r#"
outside = "bg"
priority = ["myo"]
[labels]
0 = "bg"
1 = "lv"
2 = "rv"
3 = "myo"
[[separate]]
labels = ["lv", "rv"]
by = "myo"
"#;

    fn parse(s: &str) -> Result<Config> {
        Config::from_toml_str(s, Path::new("t.toml"))
    }

    #[test]
    fn resolves_names_priority_and_separation() {
        let c = parse(HEART).unwrap();
        let (v, r) = c.resolve(vol(&[0, 1, 2, 3])).unwrap();
        assert_eq!(v.values(), &[0, 1, 2, 3]);
        assert_eq!(r.outside, 0);
        assert_eq!(r.rank[3], 0);
        assert!(r.rank[1] > r.rank[3]);
        assert_eq!(
            r.separations,
            vec![SeparationIds {
                labels: vec![1, 2],
                by: 3
            }]
        );
        assert!(r.warnings.is_empty());
    }

    #[test]
    fn separator_absent_from_volume_is_added() {
        let c = parse(HEART).unwrap();
        let (v, r) = c.resolve(vol(&[0, 1, 2])).unwrap();
        assert_eq!(v.values(), &[0, 1, 2, 3]);
        assert_eq!(r.separations[0].by, 3);
        assert_eq!(r.warnings.len(), 2, "{:?}", r.warnings);
    }

    #[test]
    fn errors_name_the_key() {
        let cases = [
            (
                "[labels]\n1 = \"a\"\n[[separate]]\nlabels = [\"a\", \"zz\"]\nby = 5\n",
                "separate[0].labels[1]",
            ),
            (
                "[labels]\n1 = \"a\"\n2 = \"b\"\n[[separate]]\nlabels = [\"a\", \"b\"]\nby = \"a\"\n",
                "separator",
            ),
            (
                "[labels]\n1 = \"a\"\n[[separate]]\nlabels = [\"a\"]\nby = 3\n",
                "at least two",
            ),
            (
                "[[separate]]\nlabels = [1, 2]\nby = 3\n[[separate]]\nlabels = [2, 1]\nby = 4\n",
                "separated by label4 here but by label3",
            ),
            (
                "[[separate]]\nlabels = [1, 2]\nby = 3\n[[separate]]\nlabels = [3, 1]\nby = 2\n",
                "contradictory",
            ),
            ("priority = [\"nope\"]\n", "priority[0]"),
            ("outside = \"nope\"\n", "outside"),
        ];
        for (text, needle) in cases {
            let c = parse(text).unwrap();
            let e = c.resolve(vol(&[0, 1, 2, 3])).unwrap_err().to_string();
            assert!(e.contains(needle), "{e} should mention {needle}");
            assert!(e.contains("t.toml"), "{e}");
        }
    }

    #[test]
    fn syntax_and_unknown_keys_are_errors() {
        for (text, needle) in [
            ("[lables]\n", "lables"),
            ("bogus = 1\n", "bogus"),
            ("[labels]\nx = \"a\"\n", "labels.\"x\""),
            ("[labels]\n1 = \"a\"\n2 = \"a\"\n", "already used"),
            ("[remesh]\ntarget = 2.0\n", "target"),
            (
                "[remesh]\nsmooth_iterations = 1e9\n",
                "remesh.smooth_iterations",
            ),
            (
                "[remesh]\nsmooth_iterations = 1000000000\n",
                "remesh.smooth_iterations",
            ),
            ("[remesh]\niterations = 1000000000\n", "remesh.iterations"),
            ("[remesh]\ntarget_edge = 0\n", "remesh.target_edge"),
            ("[remesh]\ntarget_edge = -1.0\n", "remesh.target_edge"),
            ("[remesh]\ntarget_edge = nan\n", "remesh.target_edge"),
            (
                "[remesh]\nmax_displacement = inf\n",
                "remesh.max_displacement",
            ),
            ("[labels\n", "line 1"),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{e} should mention {needle}");
            assert!(e.contains("t.toml"), "{e}");
        }
    }
}
