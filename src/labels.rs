//! Label names from the files segmentation tools write, and choosing which
//! labels to mesh.
//!
//! # Label name files ([`read_label_names`], [`parse_label_names`])
//!
//! - **JSON**: an object `{"1": "grey matter", "2": "white matter"}`, or a
//!   list `[{"value": 1, "name": "grey matter"}, ...]`;
//! - **TOML**: a `[labels]` table as in septa's config (`1 = "grey matter"`),
//!   or the same keys at the top level;
//! - **3D Slicer colour tables** (`.ctbl`, `.txt`; also FreeSurfer's
//!   `FreeSurferColorLUT.txt`): one `value name r g b a` line per label
//!   (the colour is optional; a name with spaces is everything between the
//!   value and the colour), `#` comments;
//! - **ITK-SNAP label descriptions** (`.txt`, `.label`): lines
//!   `IDX -R- -G- -B- -A-- VIS MSH "LABEL"`, `#` comments.
//!
//! The format is taken from the extension (`.json`, `.toml`, `.ctbl`) or,
//! for any other, from the content: JSON starts with `{` or `[`, an ITK-SNAP
//! line ends with a quoted name, anything else is read as a colour table.
//! A malformed line is an error naming the file and the line; so are a value
//! named twice and a name given to two values (names refer to labels, in the
//! config and in `--labels`).
//!
//! ```
//! use septa::labels::{LabelNameFormat, parse_label_names};
//! let text = "# value name r g b a\n0 Background 0 0 0 0\n1 grey matter 128 128 128 255\n";
//! let names = parse_label_names(text, "t.ctbl".as_ref(), None).unwrap();
//! assert_eq!(names.format, LabelNameFormat::ColorTable);
//! assert_eq!(names.names[&1], "grey matter");
//! ```
//!
//! # Choosing labels ([`LabelSelection`])
//!
//! Mesh only some labels: every other label is merged, before anything else
//! happens, into the outside label (or into a chosen one), as if the
//! segmentation had only the chosen labels.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::config::{Config, LabelRef};
use crate::error::{Error, Result};
use crate::volume::{LabelId, LabelVolume};

/// The formats of label name files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LabelNameFormat {
    /// `{"1": "name"}` or `[{"value": 1, "name": "name"}]`.
    Json,
    /// `[labels]` with `1 = "name"`, or the keys at the top level.
    Toml,
    /// 3D Slicer colour table (and FreeSurfer's LUT): `value name r g b a`.
    ColorTable,
    /// ITK-SNAP label description: `IDX R G B A VIS MSH "LABEL"`.
    ItkSnap,
}

impl LabelNameFormat {
    /// What the format is called in messages.
    pub fn description(self) -> &'static str {
        match self {
            LabelNameFormat::Json => "JSON label names",
            LabelNameFormat::Toml => "TOML label names",
            LabelNameFormat::ColorTable => "3D Slicer colour table",
            LabelNameFormat::ItkSnap => "ITK-SNAP label description",
        }
    }
}

/// Label names read from a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LabelNames {
    /// The file (for messages).
    pub path: PathBuf,
    /// The format it was read as.
    pub format: LabelNameFormat,
    /// Label value → name.
    pub names: BTreeMap<i64, String>,
}

/// Reads a label name file (format from the extension, else the content).
pub fn read_label_names(path: &Path) -> Result<LabelNames> {
    crate::io::check_regular_file(path)?;
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        Error::input(
            path,
            format!(
                "is not UTF-8 text (byte {}): a label name file is JSON, TOML, a 3D Slicer colour \
                 table or an ITK-SNAP label description",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    parse_label_names(&text, path, None)
}

/// The format of a label name file: `format` if given, else from the
/// extension, else from the first line that is not empty or a comment.
pub fn detect_format(text: &str, path: &Path) -> LabelNameFormat {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("json") => return LabelNameFormat::Json,
        Some("toml") => return LabelNameFormat::Toml,
        Some("ctbl") => return LabelNameFormat::ColorTable,
        _ => {}
    }
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'));
    match first {
        Some(l) if l.starts_with('{') || l.starts_with('[') => LabelNameFormat::Json,
        Some(l) if l.ends_with('"') && l.contains(char::is_whitespace) => LabelNameFormat::ItkSnap,
        Some(l) if l.contains('=') => LabelNameFormat::Toml,
        _ => LabelNameFormat::ColorTable,
    }
}

/// Parses label names (see the module docs); `path` names the file in
/// messages and gives the format by its extension unless `format` does.
pub fn parse_label_names(
    text: &str,
    path: &Path,
    format: Option<LabelNameFormat>,
) -> Result<LabelNames> {
    let format = format.unwrap_or_else(|| detect_format(text, path));
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let entries = match format {
        LabelNameFormat::Json => parse_json(text, path)?,
        LabelNameFormat::Toml => parse_toml(text, path)?,
        LabelNameFormat::ColorTable => parse_lines(text, path, format, color_table_line)?,
        LabelNameFormat::ItkSnap => parse_lines(text, path, format, itk_snap_line)?,
    };
    let mut names = BTreeMap::new();
    let mut by_name: BTreeMap<String, (i64, String)> = BTreeMap::new();
    for (at, value, name) in entries {
        let name = name.trim().to_string();
        if name.is_empty() {
            return Err(Error::config(path, at, "the label name is empty"));
        }
        if name.chars().any(char::is_control) {
            return Err(Error::config(
                path,
                at,
                format!("the name of label {value} holds a control character"),
            ));
        }
        if let Some((other, where_)) = by_name.get(&name) {
            if *other != value {
                return Err(Error::config(
                    path,
                    at,
                    format!(
                        "the name \"{name}\" is also given to label {other} ({where_}): names \
                         must be unique, they refer to labels"
                    ),
                ));
            }
        }
        if let Some(old) = names.insert(value, name.clone()) {
            return Err(Error::config(
                path,
                at,
                format!("label {value} is named twice (\"{old}\" and \"{name}\")"),
            ));
        }
        by_name.insert(name, (value, at));
    }
    Ok(LabelNames {
        path: path.to_path_buf(),
        format,
        names,
    })
}

/// `(where, value, name)` of each entry.
type Entries = Vec<(String, i64, String)>;

fn parse_json(text: &str, path: &Path) -> Result<Entries> {
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        Error::config(
            path,
            format!("line {}, column {}", e.line(), e.column()),
            format!("not valid JSON: {e}"),
        )
    })?;
    let mut out = Vec::new();
    match value {
        serde_json::Value::Object(map) => {
            for (k, v) in map {
                let at = format!("\"{k}\"");
                let value = k.trim().parse::<i64>().map_err(|_| {
                    Error::config(
                        path,
                        &at,
                        "keys must be integer label values, e.g. {\"1\": \"grey matter\"}",
                    )
                })?;
                let serde_json::Value::String(name) = v else {
                    return Err(Error::config(
                        path,
                        at,
                        format!("the name must be a string, not {v}"),
                    ));
                };
                out.push((format!("\"{k}\""), value, name));
            }
        }
        serde_json::Value::Array(items) => {
            for (i, item) in items.into_iter().enumerate() {
                let at = format!("[{i}]");
                let bad = |problem: String| Error::config(path, format!("[{i}]"), problem);
                let serde_json::Value::Object(map) = item else {
                    return Err(bad(format!(
                        "expected {{\"value\": 1, \"name\": \"...\"}}, not {item}"
                    )));
                };
                if let Some(k) = map
                    .keys()
                    .find(|k| !["value", "name"].contains(&k.as_str()))
                {
                    return Err(bad(format!(
                        "unknown key \"{k}\" (an entry has \"value\" and \"name\")"
                    )));
                }
                let value = match map.get("value") {
                    Some(v) => v.as_i64().ok_or_else(|| {
                        bad(format!("\"value\" must be an integer label value, not {v}"))
                    })?,
                    None => return Err(bad("\"value\" is missing".into())),
                };
                let name = match map.get("name") {
                    Some(serde_json::Value::String(s)) => s.clone(),
                    Some(v) => return Err(bad(format!("\"name\" must be a string, not {v}"))),
                    None => return Err(bad("\"name\" is missing".into())),
                };
                out.push((at, value, name));
            }
        }
        other => {
            return Err(Error::input(
                path,
                format!(
                    "JSON label names are an object {{\"1\": \"name\"}} or a list of \
                     {{\"value\": 1, \"name\": \"name\"}}, not {}",
                    json_kind(&other)
                ),
            ));
        }
    }
    Ok(out)
}

fn json_kind(v: &serde_json::Value) -> &'static str {
    match v {
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "a boolean",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Array(_) => "a list",
        serde_json::Value::Object(_) => "an object",
    }
}

fn parse_toml(text: &str, path: &Path) -> Result<Entries> {
    let table: toml::Table = toml::from_str(text).map_err(|e| {
        let at = match e.span() {
            Some(span) => {
                let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            }
            None => "file".to_string(),
        };
        Error::config(path, at, e.message().trim().to_string())
    })?;
    let (prefix, table) = match table.get("labels") {
        Some(toml::Value::Table(t)) if table.len() == 1 => ("labels.", t.clone()),
        Some(toml::Value::Table(_)) => {
            let other = table.keys().find(|k| *k != "labels").cloned();
            return Err(Error::config(
                path,
                other.unwrap_or_default(),
                "a label name file holds only [labels] (use -c for a whole config)",
            ));
        }
        _ => ("", table),
    };
    let mut out = Vec::new();
    for (k, v) in table {
        let at = format!("{prefix}{k}");
        let value = k.trim().parse::<i64>().map_err(|_| {
            Error::config(
                path,
                &at,
                "keys must be integer label values, e.g. `3 = \"myocardium\"`",
            )
        })?;
        let toml::Value::String(name) = v else {
            return Err(Error::config(path, at, "the name must be a string"));
        };
        out.push((at, value, name));
    }
    Ok(out)
}

/// Reads line-based formats: `line` parses one line that is neither empty
/// nor a comment into `(value, name)`.
fn parse_lines(
    text: &str,
    path: &Path,
    format: LabelNameFormat,
    line: fn(&str) -> std::result::Result<(i64, String), String>,
) -> Result<Entries> {
    let mut out = Vec::new();
    for (i, l) in text.lines().enumerate() {
        let l = l.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let at = format!("line {}", i + 1);
        let (value, name) = line(l).map_err(|problem| {
            Error::config(
                path,
                &at,
                format!("{problem} (read as a {})", format.description()),
            )
        })?;
        out.push((at, value, name));
    }
    Ok(out)
}

fn label_value(token: &str) -> std::result::Result<i64, String> {
    token
        .parse::<i64>()
        .map_err(|_| format!("`{token}` is not an integer label value"))
}

/// `value name [r g b [a]]`: the trailing numbers (3 or 4) are the colour.
fn color_table_line(l: &str) -> std::result::Result<(i64, String), String> {
    let tokens: Vec<&str> = l.split_whitespace().collect();
    let value = label_value(tokens[0])?;
    let rest = &tokens[1..];
    let numeric = rest
        .iter()
        .rev()
        .take_while(|t| t.parse::<f64>().is_ok())
        .count();
    let colour = match numeric {
        0 => 0,
        3 | 4 => numeric,
        n => {
            return Err(format!(
                "expected `value name r g b a`, but the line ends with {n} number{} after the \
                 value",
                if n == 1 { "" } else { "s" }
            ));
        }
    };
    let name_tokens = &rest[..rest.len() - colour];
    if name_tokens.is_empty() {
        return Err(format!(
            "label {value} has no name: expected `value name r g b a`"
        ));
    }
    for c in &rest[rest.len() - colour..] {
        match c.parse::<f64>() {
            Ok(x) if (0.0..=255.0).contains(&x) => {}
            _ => return Err(format!("colour component `{c}` is not between 0 and 255")),
        }
    }
    Ok((value, name_tokens.join(" ")))
}

/// `IDX -R- -G- -B- -A-- VIS MSH "LABEL"`.
fn itk_snap_line(l: &str) -> std::result::Result<(i64, String), String> {
    let Some(open) = l.find('"') else {
        return Err("expected `IDX R G B A VIS MSH \"LABEL\"`: no quoted label name".into());
    };
    let rest = &l[open + 1..];
    let Some(close) = rest.rfind('"') else {
        return Err("the label name's closing quote is missing".into());
    };
    if !rest[close + 1..].trim().is_empty() {
        return Err(format!(
            "unexpected `{}` after the quoted label name",
            rest[close + 1..].trim()
        ));
    }
    let name = rest[..close].to_string();
    if name.trim().is_empty() {
        return Err("the label name is empty".into());
    }
    let fields: Vec<&str> = l[..open].split_whitespace().collect();
    if fields.len() != 7 {
        return Err(format!(
            "expected 7 numbers (IDX R G B A VIS MSH) before the name, found {}",
            fields.len()
        ));
    }
    let value = label_value(fields[0])?;
    for (f, what) in fields[1..].iter().zip(["R", "G", "B", "A", "VIS", "MSH"]) {
        let ok = match f.parse::<f64>() {
            Ok(x) if what == "A" => (0.0..=1.0).contains(&x),
            Ok(x) => (0.0..=255.0).contains(&x),
            Err(_) => false,
        };
        if !ok {
            let range = if what == "A" { "0 to 1" } else { "0 to 255" };
            return Err(format!("{what} is `{f}`: expected a number from {range}"));
        }
    }
    Ok((value, name))
}

impl Config {
    /// The config with the names of `file` added: they win over its
    /// `[labels]` for the values both name. References by name elsewhere in
    /// the config (`outside`, `priority`, `separate`) keep the labels they
    /// named; they may also use the file's names. A name given to two values
    /// (one here, one there) is an error.
    pub fn with_label_names(&self, file: &LabelNames) -> Result<Config> {
        let mut c = self.clone();
        let fix = |r: &mut LabelRef| {
            if let LabelRef::Name(n) = r {
                if let Some((v, _)) = self.names.iter().find(|(_, name)| *name == n) {
                    *r = LabelRef::Value(*v);
                }
            }
        };
        if let Some(o) = c.outside.as_mut() {
            fix(o);
        }
        c.priority.iter_mut().for_each(fix);
        for s in &mut c.separate {
            s.labels.iter_mut().for_each(fix);
            fix(&mut s.by);
        }
        for (&v, n) in &file.names {
            c.names.insert(v, n.clone());
        }
        let mut seen: BTreeMap<&str, i64> = BTreeMap::new();
        for (&v, n) in &c.names {
            if let Some(other) = seen.insert(n, v) {
                let (in_file, in_config) = if file.names.get(&v) == Some(n) {
                    (v, other)
                } else {
                    (other, v)
                };
                let config = self
                    .path
                    .as_ref()
                    .map_or("the config".to_string(), |p| p.display().to_string());
                return Err(Error::input(
                    &file.path,
                    format!(
                        "names label {in_file} \"{n}\", the name {config} gives label \
                         {in_config}: names must be unique"
                    ),
                ));
            }
        }
        Ok(c)
    }
}

/// Which labels to mesh: the others are merged into the outside label, or
/// into `others`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LabelSelection {
    /// The labels to keep (values or names).
    pub keep: Vec<LabelRef>,
    /// The label the others become (default: the outside label).
    pub others: Option<LabelRef>,
}

/// What [`LabelSelection::apply`] did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Selected {
    /// The values kept, ascending (with the outside label and the target).
    pub kept: Vec<i64>,
    /// The value the other labels were merged into.
    pub target: i64,
    /// The values merged into it, ascending.
    pub merged: Vec<i64>,
    /// The outside label's value (kept).
    pub outside: i64,
}

impl LabelSelection {
    /// Merges every label of `volume` that is not selected into the target:
    /// `others` if given, else the outside label (`config`'s, else the most
    /// frequent label on the volume's border, as the pipeline takes it). The
    /// outside label is always kept. Returns the new volume and, for the
    /// outside label, the value to use from now on (it must not change when
    /// the border changes).
    ///
    /// Errors ([`Error::Invalid`], naming `--labels` / `--others` as
    /// `keys`): an empty selection, an unknown name, a selected label that
    /// does not occur in the volume.
    pub fn apply(
        &self,
        volume: LabelVolume,
        config: &Config,
        keys: (&str, &str),
    ) -> Result<(LabelVolume, Selected)> {
        if self.keep.is_empty() {
            return Err(Error::invalid(format!(
                "{}: no label given to mesh",
                keys.0
            )));
        }
        let outside = match &config.outside {
            Some(r) => config.value_of(r, "outside")?,
            None => volume.value(volume.most_frequent_border_label()),
        };
        let lookup = |r: &LabelRef, key: &str| -> Result<i64> {
            config.value_of(r, key).map_err(|e| match e {
                Error::Config { problem, .. } => Error::invalid(format!("{key} {r}: {problem}")),
                other => other,
            })
        };
        let mut kept = Vec::new();
        for r in &self.keep {
            let v = lookup(r, keys.0)?;
            if volume.id_of(v).is_none() {
                return Err(Error::invalid(format!(
                    "{} {r}: label {} does not occur in the volume (labels: {})",
                    keys.0,
                    config.display_name(v),
                    list_values(volume.values())
                )));
            }
            kept.push(v);
        }
        let target = match &self.others {
            Some(r) => lookup(r, keys.1)?,
            None => outside,
        };
        kept.push(outside);
        kept.push(target);
        kept.sort_unstable();
        kept.dedup();
        let merged: Vec<i64> = volume
            .values()
            .iter()
            .copied()
            .filter(|v| kept.binary_search(v).is_err())
            .collect();
        let volume = merge_into(volume, &merged, target)?;
        Ok((
            volume,
            Selected {
                kept,
                target,
                merged,
                outside,
            },
        ))
    }
}

fn list_values(values: &[i64]) -> String {
    let shown: Vec<String> = values.iter().take(20).map(i64::to_string).collect();
    if values.len() > 20 {
        format!("{}, … ({} in all)", shown.join(", "), values.len())
    } else {
        shown.join(", ")
    }
}

/// `volume` with every voxel of the values `merged` set to `target` (which
/// need not occur yet).
fn merge_into(volume: LabelVolume, merged: &[i64], target: i64) -> Result<LabelVolume> {
    use rayon::prelude::*;
    if merged.is_empty() {
        return Ok(volume);
    }
    let mut values: Vec<i64> = volume
        .values()
        .iter()
        .copied()
        .filter(|v| merged.binary_search(v).is_err())
        .chain(std::iter::once(target))
        .collect();
    values.sort_unstable();
    values.dedup();
    let new_id = |v: i64| values.binary_search(&v).map(|i| i as LabelId);
    let remap: Vec<LabelId> = volume
        .values()
        .iter()
        .map(|&v| {
            let v = if merged.binary_search(&v).is_ok() {
                target
            } else {
                v
            };
            new_id(v).map_err(|_| Error::invalid("internal error: a label lost in merging"))
        })
        .collect::<Result<_>>()?;
    let ids = volume
        .ids()
        .par_iter()
        .map(|&i| remap[i as usize])
        .collect();
    LabelVolume::from_ids(volume.dims(), ids, values, *volume.geometry())
}

/// Parses a comma-separated list of labels (`1,lv_blood, 7`): integers are
/// values, anything else a name.
pub fn parse_label_list(s: &str) -> Vec<LabelRef> {
    s.split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(parse_label_ref)
        .collect()
}

/// A label value, or else a name.
pub fn parse_label_ref(s: &str) -> LabelRef {
    match s.trim().parse::<i64>() {
        Ok(v) => LabelRef::Value(v),
        Err(_) => LabelRef::Name(s.trim().to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Dims, Geometry};

    fn parse(text: &str, file: &str) -> Result<LabelNames> {
        parse_label_names(text, Path::new(file), None)
    }

    fn err(text: &str, file: &str) -> String {
        parse(text, file).unwrap_err().to_string()
    }

    #[test]
    fn json_object_and_list() {
        let a = parse(r#"{"1": "grey matter", "2": "white matter"}"#, "n.json").unwrap();
        assert_eq!(a.format, LabelNameFormat::Json);
        assert_eq!(a.names[&1], "grey matter");
        let b = parse(
            r#"[{"value": 1, "name": "grey matter"}, {"value": -3, "name": "csf"}]"#,
            "names",
        )
        .unwrap();
        assert_eq!(b.format, LabelNameFormat::Json);
        assert_eq!(b.names[&-3], "csf");
    }

    #[test]
    fn json_errors() {
        for (text, needle) in [
            (r#"{"one": "x"}"#, "\"one\": keys must be integer"),
            (r#"{"1": 5}"#, "must be a string"),
            (r#"[{"value": 1}]"#, "[0]: \"name\" is missing"),
            (r#"[{"value": "a", "name": "x"}]"#, "must be an integer"),
            (
                r#"[{"value": 1, "name": "x", "rgb": 1}]"#,
                "unknown key \"rgb\"",
            ),
            (r#"[3]"#, "expected {\"value\""),
            ("{\"1\": \"a\",\n \"2\": }", "line 2"),
            ("5", "not a number"),
            (r#"{"1": "a", "2": "a"}"#, "also given to label 1"),
            (r#"{"1": " "}"#, "empty"),
        ] {
            let e = err(text, "n.json");
            assert!(e.contains(needle), "{e} should mention {needle}");
            assert!(e.contains("n.json"), "{e}");
        }
    }

    #[test]
    fn toml_table_or_top_level() {
        let a = parse("[labels]\n1 = \"lv\"\n2 = \"rv\"\n", "n.toml").unwrap();
        assert_eq!(a.names.len(), 2);
        let b = parse("1 = \"lv\"\n", "n.toml").unwrap();
        assert_eq!(b.names[&1], "lv");
        for (text, needle) in [
            ("[labels]\nx = \"lv\"\n", "labels.x: keys must be integer"),
            ("1 = 2\n", "must be a string"),
            ("[labels]\n1 = \"a\"\n[remesh]\n", "only [labels]"),
            ("1 = \n", "line 1"),
        ] {
            let e = err(text, "n.toml");
            assert!(e.contains(needle), "{e} should mention {needle}");
        }
    }

    #[test]
    fn slicer_color_table() {
        let text = "# Color table file\n# 3 values\n0 Background 0 0 0 0\n\
                    1 left_ventricle 255 0 0 255\n2 right atrium 0 255 0 255\n\
                    7 myocardium\n 12 3rd 1 2 3\n";
        let n = parse(text, "heart.ctbl").unwrap();
        assert_eq!(n.format, LabelNameFormat::ColorTable);
        assert_eq!(n.names[&0], "Background");
        assert_eq!(n.names[&2], "right atrium");
        assert_eq!(n.names[&7], "myocardium");
        assert_eq!(n.names[&12], "3rd");
        // detected from the content for .txt
        assert_eq!(
            parse(text, "colors.txt").unwrap().format,
            LabelNameFormat::ColorTable
        );
    }

    #[test]
    fn slicer_color_table_errors() {
        for (text, needle) in [
            (
                "0 bg 0 0 0 0\nx lv 1 2 3 4\n",
                "line 2: `x` is not an integer",
            ),
            ("0 bg 0 0 0 0\n\n1 2 3\n", "line 3"),
            ("1 lv 300 0 0 255\n", "`300` is not between 0 and 255"),
            ("1 1 2 3 4 5 6\n", "line 1"),
            ("1 lv 1 2 3\n1 rv 1 2 3\n", "named twice"),
            (
                "1 lv 1 2 3\n2 lv 1 2 3\n",
                "line 2: the name \"lv\" is also given to label 1 (line 1)",
            ),
        ] {
            let e = err(text, "t.ctbl");
            assert!(e.contains(needle), "{e} should mention {needle}");
            assert!(e.contains("t.ctbl"), "{e}");
        }
    }

    const ITK_SNAP: &str = "################################################\n\
# ITK-SnAP Label Description File\n\
# Columns = Index, Red, Green, Blue, Visibility, Mesh Visibility, Label\n\
################################################\n\
    0     0    0    0        0  0  0    \"Clear Label\"\n\
    1   255    0    0        1  1  1    \"Label 1\"\n\
    2     0  255    0      0.5  1  1    \"grey matter\"\n";

    #[test]
    fn itk_snap_label_description() {
        let n = parse(ITK_SNAP, "labels.txt").unwrap();
        assert_eq!(n.format, LabelNameFormat::ItkSnap);
        assert_eq!(n.names[&0], "Clear Label");
        assert_eq!(n.names[&1], "Label 1");
        assert_eq!(n.names[&2], "grey matter");
    }

    #[test]
    fn itk_snap_errors() {
        for (text, needle) in [
            (
                "1 255 0 0 1 1 1 \"a\"\n2 0 0 0 1 1 \"b\"\n",
                "line 2: expected 7 numbers",
            ),
            ("1 255 0 0 2 1 1 \"a\"\n", "A is `2`"),
            ("1 255 0 0 1 1 1 \"a\" x\n", "after the quoted"),
            ("q 255 0 0 1 1 1 \"a\"\n", "`q` is not an integer"),
            (
                "1 255 0 0 1 1 1 \"a\"\n2 0 0 0 1 1 1 \"\"\n",
                "line 2: the label name is empty",
            ),
        ] {
            let e = parse_label_names(text, Path::new("l.label"), Some(LabelNameFormat::ItkSnap))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{e} should mention {needle}");
            assert!(e.contains("ITK-SNAP"), "{e}");
        }
    }

    #[test]
    fn names_join_the_config_and_keep_its_references() {
        let config = Config::from_toml_str(
            "priority = [\"myo\"]\n[labels]\n1 = \"lv\"\n3 = \"myo\"\n",
            Path::new("c.toml"),
        )
        .unwrap();
        let file = parse(r#"{"3": "myocardium", "4": "aorta"}"#, "n.json").unwrap();
        let c = config.with_label_names(&file).unwrap();
        assert_eq!(c.name_of(1), Some("lv"));
        assert_eq!(c.name_of(3), Some("myocardium"));
        assert_eq!(c.name_of(4), Some("aorta"));
        assert_eq!(c.priority, vec![LabelRef::Value(3)]);
        let clash = parse(r#"{"4": "lv"}"#, "n.json").unwrap();
        let e = config.with_label_names(&clash).unwrap_err().to_string();
        assert!(e.contains("n.json") && e.contains("c.toml"), "{e}");
    }

    fn volume(values: &[i64]) -> LabelVolume {
        LabelVolume::from_values(
            Dims::new(values.len(), 1, 1).unwrap(),
            values,
            Geometry::identity(),
        )
        .unwrap()
    }

    #[test]
    fn selection_merges_the_others() {
        let v = volume(&[0, 1, 2, 3, 2, 0]);
        let config = Config::default();
        let sel = LabelSelection {
            keep: parse_label_list("1, 3"),
            others: None,
        };
        let (out, s) = sel
            .apply(v.clone(), &config, ("--labels", "--others"))
            .unwrap();
        assert_eq!(out.values(), &[0, 1, 3]);
        assert_eq!(s.merged, vec![2]);
        assert_eq!(s.target, 0);
        let values: Vec<i64> = out.ids().iter().map(|&i| out.value(i)).collect();
        assert_eq!(values, [0, 1, 0, 3, 0, 0]);
        // into a chosen label
        let sel = LabelSelection {
            keep: vec![LabelRef::Value(1)],
            others: Some(LabelRef::Value(3)),
        };
        let (out, s) = sel
            .apply(v.clone(), &config, ("--labels", "--others"))
            .unwrap();
        assert_eq!(s.merged, vec![2]);
        let values: Vec<i64> = out.ids().iter().map(|&i| out.value(i)).collect();
        assert_eq!(values, [0, 1, 3, 3, 3, 0]);
    }

    #[test]
    fn selection_errors() {
        let v = volume(&[0, 1, 2]);
        let config = Config::default();
        let keys = ("--labels", "--others");
        for (sel, needle) in [
            (LabelSelection::default(), "no label"),
            (
                LabelSelection {
                    keep: vec![LabelRef::Value(9)],
                    others: None,
                },
                "does not occur",
            ),
            (
                LabelSelection {
                    keep: vec![LabelRef::Name("lv".into())],
                    others: None,
                },
                "--labels \"lv\": unknown label name",
            ),
            (
                LabelSelection {
                    keep: vec![LabelRef::Value(1)],
                    others: Some(LabelRef::Name("x".into())),
                },
                "--others \"x\"",
            ),
        ] {
            let e = sel.apply(v.clone(), &config, keys).unwrap_err().to_string();
            assert!(e.contains(needle), "{e} should mention {needle}");
        }
    }
}
