//! Errors of TOML configuration files (drone profiles, site files), with file and line.

use std::fmt;
use std::path::{Path, PathBuf};

/// A configuration file that cannot be used: which file, which line (1-based, when known),
/// and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file (or a name such as `<string>` for text not read from a file).
    pub path: PathBuf,
    /// 1-based line of the offending item, if known.
    pub line: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

impl std::error::Error for ConfigError {}

/// 1-based line number of a byte offset in `text`.
pub fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// Parses TOML `text` (read from `path`) into `T`, turning syntax and type errors into a
/// [`ConfigError`] with the line the parser points at.
pub fn parse_toml<T: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| toml_error(text, path, &e))
}

/// A TOML syntax or type error in `text` (read from `path`) as a [`ConfigError`] on one line,
/// with the line the parser points at (the parser's own text spans several lines, with a
/// drawing of the line).
pub fn toml_error(text: &str, path: &Path, e: &toml::de::Error) -> ConfigError {
    let line = e.span().map(|s| line_of(text, s.start));
    let message = e.message().trim().replace('\n', " ");
    // A type error names the value, not its key (`invalid type: string "north", expected
    // f64`): the key of that line leads the message when the message does not name it.
    let key = line
        .and_then(|l| text.lines().nth(l - 1))
        .and_then(|l| l.split_once('='))
        .map(|(k, _)| k.trim())
        .filter(|k| {
            !k.is_empty()
                && !k.starts_with(['[', '#'])
                && k.chars().all(|c| c.is_alphanumeric() || matches!(c, '_' | '-' | '.' | '"'))
        });
    let message = match key {
        Some(k) if !message.contains(&format!("`{k}`")) => format!("{k}: {message}"),
        _ => message,
    };
    ConfigError { path: path.to_path_buf(), line, message }
}

/// Reads a file to a string, with the path in the error.
pub fn read_text(path: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(path).map_err(|e| ConfigError {
        path: path.to_path_buf(),
        line: None,
        message: format!("cannot read: {e}"),
    })
}

/// Checks a spanned number against a predicate, reporting its line when it fails.
pub fn check(
    value: &toml::Spanned<f64>,
    ok: impl Fn(f64) -> bool,
    what: &str,
    text: &str,
    path: &Path,
) -> Result<f64, ConfigError> {
    let v = *value.get_ref();
    if v.is_finite() && ok(v) {
        Ok(v)
    } else {
        Err(ConfigError {
            path: path.to_path_buf(),
            line: Some(line_of(text, value.span().start)),
            message: format!("{what} (got {v:?})"),
        })
    }
}

/// Checks a number given on the command line: finite and within `range`, else an error that
/// names the flag, the range and the value (`--period must be 0.001 to 60.0 s, not 1e-12`).
pub fn check_flag(
    value: f64,
    flag: &str,
    range: std::ops::RangeInclusive<f64>,
    unit: &str,
) -> anyhow::Result<f64> {
    if value.is_finite() && range.contains(&value) {
        Ok(value)
    } else {
        anyhow::bail!(
            "{flag} must be {:?} to {:?} {unit}, not {value:?}",
            range.start(),
            range.end()
        )
    }
}

/// Range of `aim replay`/`aim track --period`, s: one fix per millisecond at most (a finer
/// period only repeats the filter's prediction and, over a long run, fills memory with fixes),
/// one a minute at least.
pub const PERIOD_RANGE_S: std::ops::RangeInclusive<f64> = 1e-3..=60.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_out_of_range_name_the_flag() {
        for bad in [1e-12, 0.0, -1.0, f64::NAN, f64::INFINITY, 1e9] {
            let e = check_flag(bad, "--period", PERIOD_RANGE_S, "s").unwrap_err().to_string();
            assert!(e.starts_with("--period must be 0.001 to 60.0 s, not "), "{e}");
        }
        assert_eq!(check_flag(0.1, "--period", PERIOD_RANGE_S, "s").unwrap(), 0.1);
    }

    /// A type error leads with its key and its line; an error that names its key already
    /// (unknown or missing field) is left as it is.
    #[test]
    fn toml_errors_name_the_key_and_the_line() {
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct T {
            a: f64,
            yaw_deg: f64,
        }
        let e = parse_toml::<T>("a = 1.0\nyaw_deg = \"north\"\n", Path::new("t.toml")).unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
        assert!(e.message.starts_with("yaw_deg: invalid type: string \"north\""), "{e}");
        let e =
            parse_toml::<T>("a = 1.0\nyaw_deg = 2.0\nb = 3\n", Path::new("t.toml")).unwrap_err();
        assert_eq!((e.line, e.message.starts_with("unknown field `b`")), (Some(3), true), "{e}");
    }
}

/// `N` numbers of a configuration file, exactly `N`: serde reads `[f64; N]` from the first `N`
/// elements of a longer TOML array and drops the rest without a word (`position = [1, 2, 0.05,
/// 9]` was read as `[1, 2, 0.05]`); this type refuses it with the count, at the value's line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coords<const N: usize>(pub [f64; N]);

/// Reads a sequence of exactly `N` numbers for a serde visitor; a sequence of another length
/// is an `invalid_length` error that says what was `expected` (the visitor's own wording).
pub fn exactly_from_seq<'de, A: serde::de::SeqAccess<'de>, const N: usize>(
    mut seq: A,
    expected: &dyn serde::de::Expected,
) -> Result<[f64; N], A::Error> {
    let mut out = [0.0; N];
    let mut n = 0;
    while let Some(v) = seq.next_element::<f64>()? {
        if let Some(slot) = out.get_mut(n) {
            *slot = v;
        }
        n += 1;
    }
    if n != N {
        return Err(serde::de::Error::invalid_length(n, expected));
    }
    Ok(out)
}

/// `#[serde(deserialize_with = "aim_tracker::config::exactly")]` for a plain `[f64; N]` field:
/// exactly `N` numbers, as [`Coords`] reads them.
pub fn exactly<'de, D: serde::Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<[f64; N], D::Error> {
    <Coords<N> as serde::Deserialize>::deserialize(d).map(|c| c.0)
}

impl<const N: usize> std::ops::Deref for Coords<N> {
    type Target = [f64; N];
    fn deref(&self) -> &[f64; N] {
        &self.0
    }
}

impl<'de, const N: usize> serde::Deserialize<'de> for Coords<N> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Exactly<const N: usize>;
        impl<'de, const N: usize> serde::de::Visitor<'de> for Exactly<N> {
            type Value = Coords<N>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "an array of {N} numbers")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> Result<Self::Value, A::Error> {
                exactly_from_seq(seq, &self).map(Coords)
            }
        }
        d.deserialize_seq(Exactly::<N>)
    }
}
