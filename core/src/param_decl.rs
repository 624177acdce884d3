//! How a tunable parameter is declared, beside the struct that holds it: [`Param`] (MAVLink
//! name, ground-station group, unit, range, decimals, description, scene/option key, code
//! labels and how it reads and writes its field), [`Has`] (how the whole parameter set reaches
//! that struct) and the access macros [`field!`], [`u8_field!`], [`flag!`], [`access!`].
//!
//! Each parameters struct lists its own parameters in an inherent `const fn`, generic over the
//! set `P` that holds it, e.g. in `safety/cbf.rs`:
//!
//! ```ignore
//! impl CbfParams {
//!     pub const fn params<P: Has<Self>>() -> [Param<P>; 4] {
//!         [Param::new("CBF_MU", "CBF", "s", (0.01, 100.0), 2, field!(mu),
//!             "Barrier velocity weight mu").key("mu"), /* … */]
//!     }
//! }
//! ```
//!
//! and [`crate::params`] concatenates the lists into the one table over
//! [`crate::config::ControllerParams`] (which implements `Has<CbfParams>`, …). The default is
//! the struct's own `Default`, so a parameter's name, unit, range, meaning and default are all
//! written in the stage's file, once.
//!
//! Owns: [`Param`], [`Has`], [`Access`], [`ParamRejected`], [`HostText`], the access macros.
//! Imports nothing of the crate (every stage may import it). No allocation, no panics.

/// Text only host tools read ([`Param::description`], [`Param::key`]): the string on the host,
/// [`NoText`] on the flight controller (`target_os = "none"`). Read by `cargo xtask params`, the
/// scene parser and the QGC metadata; on the F405 the strings would take ~5 KB of the 128 KiB
/// flash, and even empty ones 16 bytes per table entry (~1.1 KB).
#[cfg(not(target_os = "none"))]
pub type HostText = &'static str;
/// Text only host tools read: nothing on the flight controller (see the host build's doc).
#[cfg(target_os = "none")]
pub type HostText = NoText;

/// [`HostText`] on the flight controller: zero-sized, the text is not in the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NoText;

/// `s` on the host, [`NoText`] on the flight controller (see [`HostText`]).
pub const fn host_text(s: &'static str) -> HostText {
    #[cfg(target_os = "none")]
    {
        let _ = s;
        NoText
    }
    #[cfg(not(target_os = "none"))]
    s
}

/// A parameter set `Self` holds the parameters struct `S` (the table reaches a stage's fields
/// through it: `crate::config::ControllerParams` implements it once per stage struct).
pub trait Has<S> {
    /// The stage's struct.
    fn part(&self) -> &S;
    /// The stage's struct, to write.
    fn part_mut(&mut self) -> &mut S;
}

/// Reads and writes of a parameter in the set `P`: `(get, write)` ([`Param::get`], the
/// private write).
pub type Access<P> = (fn(&P) -> f32, fn(&mut P, f32));

/// The [`Access`] of the parameter `s.EXPR` of the struct `Self` (in a stage's
/// `params::<P: Has<Self>>()`): `access!(|s| s.kp[0], |s, v| s.kp = [v; 3])`.
macro_rules! access {
    (|$s:ident| $get:expr, |$w:ident, $v:ident| $set:expr) => {
        (
            |p| {
                let $s = $crate::param_decl::Has::<Self>::part(p);
                $get
            },
            |p, $v| {
                let $w = $crate::param_decl::Has::<Self>::part_mut(p);
                $set
            },
        )
    };
}

/// The [`Access`] of an `f32` field of the struct `Self`: `field!(mu)`, `field!(accel_offset.x)`.
macro_rules! field {
    ($($path:tt)+) => {
        $crate::param_decl::access!(|s| s.$($path)+, |s, v| s.$($path)+ = v)
    };
}

/// The [`Access`] of a `u8` field (a count or channel; written from a checked whole value).
macro_rules! u8_field {
    ($($path:tt)+) => {
        $crate::param_decl::access!(|s| f32::from(s.$($path)+), |s, v| s.$($path)+ = v as u8)
    };
}

/// The [`Access`] of a `bool` field (1 = on).
macro_rules! flag {
    ($($path:tt)+) => {
        $crate::param_decl::access!(|s| f32::from(u8::from(s.$($path)+)), |s, v| s.$($path)+ = v != 0.0)
    };
}

pub(crate) use {access, field, flag, u8_field};

/// Labels of an on/off flag's codes (0 off, 1 on), for [`Param::code`].
pub fn on_off(code: i32) -> Option<&'static str> {
    match code {
        0 => Some("off"),
        1 => Some("on"),
        _ => None,
    }
}

/// Why a value was not taken (the parameter keeps its value).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamRejected {
    /// No such parameter.
    Unknown,
    /// Not finite, outside the parameter's range, or not a whole number for a code.
    Invalid,
    /// Not now (e.g. while armed).
    NotNow,
}

/// One parameter of the set `P`: the single place its name, unit, range and meaning are
/// written, beside its field; its default is the one of the field's struct (`CbfParams::default()`,
/// …), read through [`Param::get`] (`crate::params::Param::default_value`).
pub struct Param<P> {
    /// MAVLink `param_id` (≤ 16 ASCII bytes), e.g. `CBF_MU`.
    pub name: &'static str,
    /// Key of the scene file's `[controller]` table and of the `parapet` command-line
    /// option (`--key`), when the host exposes the parameter there; `None` otherwise
    /// (the vehicle parameters come from the scene's `[vehicle]` table instead). Host builds
    /// only (see [`HostText`]).
    pub key: Option<HostText>,
    /// Unit (SI), `""` for codes and flags.
    pub unit: &'static str,
    /// Smallest allowed value.
    pub min: f32,
    /// Largest allowed value.
    pub max: f32,
    /// `true` for codes and flags: only whole numbers in `[min, max]`.
    pub integer: bool,
    /// Decimal places a ground station should show.
    pub decimals: u8,
    /// Ground-station group (`CBF`, `Tracking`, …).
    pub group: &'static str,
    /// One-line description (host builds only, see [`HostText`]).
    pub description: HostText,
    /// Names of the values of a code parameter (`None` for a continuous one).
    pub label: Option<fn(i32) -> Option<&'static str>>,
    /// Reads the parameter from a set.
    pub get: fn(&P) -> f32,
    /// Writes a value that [`Param::check`] accepted.
    pub(crate) write: fn(&mut P, f32),
}

// By hand: a derive would ask `P: Copy`, and the entry is plain data whatever `P` is.
impl<P> Clone for Param<P> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<P> Copy for Param<P> {}

impl<P> Param<P> {
    /// A continuous parameter without a scene/option key: `name`, ground-station `group`, SI
    /// `unit`, allowed `(min, max)`, `decimals` shown, how it is read and written
    /// (`field!(mu)` for an `f32` field) and a one-line `description`. Chain [`Param::key`],
    /// [`Param::whole`], [`Param::code`].
    pub const fn new(
        name: &'static str,
        group: &'static str,
        unit: &'static str,
        (min, max): (f32, f32),
        decimals: u8,
        (get, write): Access<P>,
        description: &'static str,
    ) -> Self {
        Param {
            name,
            key: None,
            unit,
            min,
            max,
            integer: false,
            decimals,
            group,
            description: host_text(description),
            label: None,
            get,
            write,
        }
    }

    /// The scene file's `[controller]` key and command-line option of this parameter.
    pub const fn key(self, key: &'static str) -> Self {
        Param { key: Some(host_text(key)), ..self }
    }

    /// Only whole numbers (counts, flags).
    pub const fn whole(self) -> Self {
        Param { integer: true, ..self }
    }

    /// A code: whole numbers, each named by `label`.
    pub const fn code(self, label: fn(i32) -> Option<&'static str>) -> Self {
        Param { integer: true, label: Some(label), ..self }
    }

    /// `value` if this parameter accepts it: finite, in `[min, max]`, whole for codes.
    pub fn check(&self, value: f32) -> Result<f32, ParamRejected> {
        // `!(a ≤ x ≤ b)` also refuses NaN; ±∞ are outside every finite range.
        if !(value >= self.min && value <= self.max) {
            return Err(ParamRejected::Invalid);
        }
        // In range, so the cast cannot saturate: whole numbers survive the round trip.
        if self.integer && (value as i32) as f32 != value {
            return Err(ParamRejected::Invalid);
        }
        Ok(value)
    }

    /// The allowed values in words, e.g. `0.01 ≤ CBF_MU ≤ 100 s` (for messages).
    pub fn range(&self) -> RangeText<'_, P> {
        RangeText(self)
    }
}

/// [`Param::range`]'s `Display`.
pub struct RangeText<'a, P>(&'a Param<P>);

impl<P> core::fmt::Display for RangeText<'_, P> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let p = self.0;
        #[cfg(not(target_os = "none"))]
        let name = p.key.unwrap_or(p.name);
        #[cfg(target_os = "none")]
        let name = p.name;
        if p.integer {
            write!(f, "{name} one of")?;
            let (lo, hi) = (p.min as i32, p.max as i32);
            for c in lo..=hi {
                match p.label.and_then(|l| l(c)) {
                    Some(s) => write!(f, " {c} ({s})")?,
                    None => write!(f, " {c}")?,
                }
            }
            Ok(())
        } else {
            write!(f, "{} ≤ {name} ≤ {}", p.min, p.max)?;
            if !p.unit.is_empty() {
                write!(f, " {}", p.unit)?;
            }
            Ok(())
        }
    }
}
