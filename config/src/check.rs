//! Range checks shared by scene and daemon validation. Every check is written so that NaN fails
//! it (`v.is_finite() && v > 0.0`, never `!(v <= 0.0)`), and every failure names the key path,
//! the body (if any) and the value as TOML spells it.

use std::fmt::Display;

use crate::error::ConfigError;
use crate::source::{KeyPath, Source};

/// A float as TOML spells it: `nan`, `inf`, `-inf`, else Rust's shortest round-trip form.
pub(crate) fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        "nan".to_owned()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else {
        format!("{v:?}")
    }
}

/// A float array as TOML spells it.
pub(crate) fn fmt_f64s(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| fmt_f64(*x)).collect();
    format!("[{}]", items.join(", "))
}

/// Validation helpers bound to one file and, optionally, one body.
pub(crate) struct Check<'s, 'a> {
    pub(crate) src: &'s Source<'a>,
    pub(crate) body: Option<&'s str>,
}

impl Check<'_, '_> {
    /// A [`ConfigError::Invalid`] located at `key`.
    pub(crate) fn invalid(
        &self,
        key: &KeyPath,
        value: impl Display,
        reason: impl Into<String>,
    ) -> ConfigError {
        ConfigError::Invalid {
            at: Box::new(self.src.locate(key)),
            key: key.to_string(),
            body: self.body.map(str::to_owned),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// `v` finite and `> 0`.
    pub(crate) fn positive(&self, key: &KeyPath, v: f64, what: &str) -> Result<f64, ConfigError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64(v),
                format!("{what} must be a finite number > 0"),
            ))
        }
    }

    /// `v` finite and `>= 0`.
    pub(crate) fn non_negative(
        &self,
        key: &KeyPath,
        v: f64,
        what: &str,
    ) -> Result<f64, ConfigError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64(v),
                format!("{what} must be a finite number >= 0"),
            ))
        }
    }

    /// `lo <= v <= hi` (both finite).
    pub(crate) fn within(
        &self,
        key: &KeyPath,
        v: f64,
        lo: f64,
        hi: f64,
        what: &str,
    ) -> Result<f64, ConfigError> {
        if v >= lo && v <= hi {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64(v),
                format!("{what} must be between {} and {}", fmt_f64(lo), fmt_f64(hi)),
            ))
        }
    }

    /// A time step: finite, `> 0` and at most one second (a larger value is almost surely
    /// milliseconds written as seconds).
    pub(crate) fn time_step(&self, key: &KeyPath, v: f64) -> Result<f64, ConfigError> {
        if v.is_finite() && v > 0.0 && v <= 1.0 {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64(v),
                "time step dt must be > 0 and <= 1 (seconds; 0.01 is 10 ms)",
            ))
        }
    }

    /// A temperature, °C: above absolute zero (-273.15 °C) and at most 1000 °C (a larger value
    /// is almost surely kelvin or a typo).
    pub(crate) fn temperature(
        &self,
        key: &KeyPath,
        v: f64,
        what: &str,
    ) -> Result<f64, ConfigError> {
        if v > -273.15 && v <= 1000.0 {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64(v),
                format!("{what} must be in °C, above -273.15 and at most 1000"),
            ))
        }
    }

    /// Every component finite.
    pub(crate) fn finite3(
        &self,
        key: &KeyPath,
        v: [f64; 3],
        what: &str,
    ) -> Result<[f64; 3], ConfigError> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(v)
        } else {
            Err(self.invalid(
                key,
                fmt_f64s(&v),
                format!("{what} must be three finite numbers"),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_print_as_toml_spells_them() {
        assert_eq!(fmt_f64(f64::NAN), "nan");
        assert_eq!(fmt_f64(f64::INFINITY), "inf");
        assert_eq!(fmt_f64(f64::NEG_INFINITY), "-inf");
        assert_eq!(fmt_f64(-5.0), "-5.0");
        assert_eq!(fmt_f64(1e300), "1e300");
        assert_eq!(fmt_f64s(&[0.5, f64::NAN]), "[0.5, nan]");
    }
}
