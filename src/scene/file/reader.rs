//! The spanned TOML reader under the scene-file schema: the document, its sections and
//! typed, range-checked reads that name `file:line: key` in every error.

use crate::scene::error::SceneError;
use glam::Vec3;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;
use toml::de::{DeTable, DeValue};

/// The file being read: its path, folder and line starts.
pub(super) struct Doc<'a> {
    pub(super) path: &'a Path,
    pub(super) dir: PathBuf,
    pub(super) line_starts: Vec<usize>,
}

/// A table of the document with its dotted name (`materials.glass`, `spheres[2]`).
pub(super) struct Section<'t, 'i> {
    pub(super) table: &'t DeTable<'i>,
    pub(super) name: String,
    pub(super) span: Range<usize>,
}

pub(super) type Value<'t, 'i> = &'t Spanned<DeValue<'i>>;

impl<'t, 'i> Section<'t, 'i> {
    pub(super) fn key(&self, k: &str) -> String {
        if self.name.is_empty() {
            k.to_string()
        } else {
            format!("{}.{k}", self.name)
        }
    }

    pub(super) fn get(&self, k: &str) -> Option<Value<'t, 'i>> {
        self.table
            .iter()
            .find(|(key, _)| key.get_ref().as_ref() == k)
            .map(|(_, v)| v)
    }
}

pub(super) fn is_number(v: &DeValue) -> bool {
    matches!(v, DeValue::Integer(_) | DeValue::Float(_))
}

impl<'a> Doc<'a> {
    pub(super) fn new(path: &'a Path, text: &str) -> Doc<'a> {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Doc {
            path,
            dir: path.parent().unwrap_or(Path::new("")).to_path_buf(),
            line_starts,
        }
    }

    /// 1-based line of byte `offset`.
    pub(super) fn line(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= offset).max(1)
    }

    /// The line of a TOML error reported without a position (the parser's recursion
    /// limit on deeply nested dotted keys): the first line whose prefix of the file fails
    /// with the same `message`, found by bisection (`O(n log n)`, on the error path only).
    pub(super) fn first_failing_line(&self, text: &str, message: &str) -> usize {
        let fails = |lines: usize| {
            let end = self.line_starts.get(lines).map_or(text.len(), |&e| e);
            DeTable::parse(&text[..end]).is_err_and(|e| e.message() == message)
        };
        let (mut lo, mut hi) = (1, self.line_starts.len());
        if !fails(hi) {
            return 0;
        }
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if fails(mid) { hi = mid } else { lo = mid + 1 }
        }
        lo
    }

    pub(super) fn invalid(
        &self,
        span: &Range<usize>,
        key: String,
        message: impl Into<String>,
    ) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            line: self.line(span.start),
            key,
            message: message.into(),
        }
    }

    /// Rejects keys of `s` not in `allowed`, suggesting the closest allowed one.
    pub(super) fn check_keys(&self, s: &Section, allowed: &[&str]) -> Result<(), SceneError> {
        for (key, _) in s.table.iter() {
            let k: &str = key.get_ref().as_ref();
            if allowed.contains(&k) {
                continue;
            }
            let suggestion = allowed
                .iter()
                .map(|a| (strsim::damerau_levenshtein(k, a), *a))
                .min()
                .filter(|&(d, a)| d <= (a.len().max(k.len()) / 3).max(2))
                .map(|(_, a)| a.to_string());
            return Err(SceneError::UnknownKey {
                path: self.path.to_path_buf(),
                line: self.line(key.span().start),
                key: s.key(k),
                suggestion,
            });
        }
        Ok(())
    }

    pub(super) fn required<'t, 'i>(
        &self,
        s: &Section<'t, 'i>,
        k: &str,
    ) -> Result<Value<'t, 'i>, SceneError> {
        s.get(k)
            .ok_or_else(|| self.invalid(&s.span, s.key(k), "missing (this key is required)"))
    }

    pub(super) fn wrong_type(&self, v: &Spanned<DeValue>, key: String, want: &str) -> SceneError {
        self.invalid(
            &v.span(),
            key,
            format!("expected {want}, found {}", v.get_ref().type_str()),
        )
    }

    /// A finite number that fits an `f32` (integers are accepted).
    pub(super) fn number(&self, v: &Spanned<DeValue>, key: &str) -> Result<f32, SceneError> {
        let x = match v.get_ref() {
            DeValue::Float(f) => f.as_str().parse::<f64>().ok(),
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|i| i as f64),
            _ => return Err(self.wrong_type(v, key.into(), "a number")),
        };
        match x.map(|x| x as f32) {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.invalid(
                &v.span(),
                key.into(),
                "not a finite number (NaN, infinite, or too large for 32-bit floats)",
            )),
        }
    }

    pub(super) fn integer(&self, v: &Spanned<DeValue>, key: &str) -> Result<i64, SceneError> {
        match v.get_ref() {
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .map_err(|_| self.invalid(&v.span(), key.into(), "integer too large")),
            _ => Err(self.wrong_type(v, key.into(), "an integer")),
        }
    }

    pub(super) fn string<'v>(
        &self,
        v: &'v Spanned<DeValue>,
        key: &str,
    ) -> Result<&'v str, SceneError> {
        v.get_ref()
            .as_str()
            .ok_or_else(|| self.wrong_type(v, key.into(), "a string"))
    }

    pub(super) fn vector<const N: usize>(
        &self,
        v: &Spanned<DeValue>,
        key: &str,
    ) -> Result<[f32; N], SceneError> {
        let want = || format!("an array of {N} numbers");
        let Some(items) = v.get_ref().as_array() else {
            return Err(self.wrong_type(v, key.into(), &want()));
        };
        if items.len() != N || !items.iter().all(|i| is_number(i.get_ref())) {
            return Err(self.invalid(&v.span(), key.into(), format!("expected {}", want())));
        }
        let mut out = [0.0; N];
        for (o, i) in out.iter_mut().zip(items.iter()) {
            *o = self.number(i, key)?;
        }
        Ok(out)
    }

    /// Optional number in `range` (inclusive ends), with `default`.
    pub(super) fn f32_in(
        &self,
        s: &Section,
        k: &str,
        default: f32,
        range: (f32, f32),
    ) -> Result<f32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.number(v, &s.key(k))?;
        if x < range.0 || x > range.1 {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; valid: {} to {}", range.0, range.1),
            ));
        }
        Ok(x)
    }

    /// Optional number greater than 0 and at most `max`, with `default`.
    pub(super) fn positive(
        &self,
        s: &Section,
        k: &str,
        default: f32,
        max: f32,
    ) -> Result<f32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.number(v, &s.key(k))?;
        if !(x > 0.0 && x <= max) {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; must be > 0 and <= {max}"),
            ));
        }
        Ok(x)
    }

    /// Optional integer in `lo..=hi`, with `default`.
    pub(super) fn u32_in(
        &self,
        s: &Section,
        k: &str,
        default: u32,
        lo: u32,
        hi: u32,
    ) -> Result<u32, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(default);
        };
        let x = self.integer(v, &s.key(k))?;
        if x < lo as i64 || x > hi as i64 {
            return Err(self.invalid(
                &v.span(),
                s.key(k),
                format!("{x} is out of range; valid: {lo} to {hi}"),
            ));
        }
        Ok(x as u32)
    }

    pub(super) fn vec3(
        &self,
        s: &Section,
        k: &str,
        default: Option<Vec3>,
    ) -> Result<Vec3, SceneError> {
        match (s.get(k), default) {
            (Some(v), _) => Ok(Vec3::from_array(self.vector::<3>(v, &s.key(k))?)),
            (None, Some(d)) => Ok(d),
            (None, None) => Err(self.required(s, k).unwrap_err()),
        }
    }

    /// A colour: three numbers, each >= 0.
    pub(super) fn color(&self, s: &Section, k: &str, default: Vec3) -> Result<Vec3, SceneError> {
        let c = self.vec3(s, k, Some(default))?;
        if c.min_element() < 0.0 {
            let span = s.get(k).map_or(s.span.clone(), |v| v.span());
            return Err(self.invalid(&span, s.key(k), "colour components must be >= 0"));
        }
        Ok(c)
    }

    pub(super) fn nonzero_vec3(
        &self,
        s: &Section,
        k: &str,
    ) -> Result<(Vec3, Range<usize>), SceneError> {
        let v = self.required(s, k)?;
        let x = Vec3::from_array(self.vector::<3>(v, &s.key(k))?);
        if x.length_squared() == 0.0 || !x.length_squared().is_finite() {
            return Err(self.invalid(&v.span(), s.key(k), "must be a non-zero vector"));
        }
        Ok((x, v.span()))
    }

    /// The named sub-table `k` of `s`, if present.
    pub(super) fn table<'t, 'i>(
        &self,
        s: &Section<'t, 'i>,
        k: &str,
    ) -> Result<Option<Section<'t, 'i>>, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(None);
        };
        match v.get_ref().as_table() {
            Some(t) => Ok(Some(Section {
                table: t,
                name: s.key(k),
                span: v.span(),
            })),
            None => Err(self.wrong_type(v, s.key(k), "a table")),
        }
    }

    /// The tables of array `k` (`[[k]]`), named `k[0]`, `k[1]`, ...
    pub(super) fn tables<'t, 'i>(
        &self,
        s: &Section<'t, 'i>,
        k: &str,
    ) -> Result<Vec<Section<'t, 'i>>, SceneError> {
        let Some(v) = s.get(k) else {
            return Ok(Vec::new());
        };
        let Some(items) = v.get_ref().as_array() else {
            return Err(self.wrong_type(v, s.key(k), "an array of tables ([[...]])"));
        };
        items
            .iter()
            .enumerate()
            .map(|(i, item)| match item.get_ref().as_table() {
                Some(t) => Ok(Section {
                    table: t,
                    name: format!("{}[{i}]", s.key(k)),
                    span: item.span(),
                }),
                None => Err(self.wrong_type(item, format!("{}[{i}]", s.key(k)), "a table")),
            })
            .collect()
    }

    /// The file named by key `k`, relative to the scene file's folder.
    pub(super) fn file(&self, s: &Section, k: &str) -> Result<(PathBuf, Range<usize>), SceneError> {
        let v = self.required(s, k)?;
        let name = self.string(v, &s.key(k))?;
        if name.is_empty() {
            return Err(self.invalid(&v.span(), s.key(k), "empty file name"));
        }
        Ok((self.dir.join(name), v.span()))
    }
}
