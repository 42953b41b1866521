//! A camera's parameter values as files write them: a table of keys, each model's own.
//!
//! Each model's keys, in its slice order, are its line's in the camera crate's registry
//! ([`pingcal_camera::ModelKind::keys`]): the photogrammetric models' `c_mm`, `xp_mm`,
//! `yp_mm`, `k1` … `b2` (mm, mm⁻², …, as Australis), the others' their parameters' names
//! (px; coefficients unitless).
//!
//! [`KeyedValues`] is such a table as read (the keys in the file's order, nothing checked);
//! [`Intrinsics`] is a model with one value per parameter in the model's slice order, what
//! `project.toml`'s `initial`, `results.json`'s cameras and `truth.json` hold, written back
//! as the same table.

use crate::closed_sets::CameraModel;
use serde::de::{MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// The keys of the two photogrammetric models' parameters in files.
pub const PHOTOGRAMMETRIC_KEYS: [&str; 10] = pingcal_camera::MM_KEYS;

/// The keys of `model`'s parameters in files, in its slice order (see the module doc; the
/// camera crate's registry holds them, [`pingcal_camera::ModelKind::keys`]).
pub fn keys(model: CameraModel) -> &'static [&'static str] {
    model.keys()
}

/// A table of numbers as a file gives it: keys and values in the file's order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KeyedValues(pub Vec<(String, f64)>);

impl KeyedValues {
    /// The value of `key`, if the table has it.
    pub fn get(&self, key: &str) -> Option<f64> {
        self.0.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
    }

    /// Sets `key` to `value`, appending it when the table has no such key.
    pub fn set(&mut self, key: &str, value: f64) {
        match self.0.iter_mut().find(|(k, _)| k == key) {
            Some((_, v)) => *v = value,
            None => self.0.push((key.to_string(), value)),
        }
    }
}

impl Serialize for KeyedValues {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

impl<'de> Deserialize<'de> for KeyedValues {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = KeyedValues;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a table of numbers")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<KeyedValues, A::Error> {
                let mut out = Vec::new();
                while let Some((k, v)) = map.next_entry::<String, f64>()? {
                    out.push((k, v));
                }
                Ok(KeyedValues(out))
            }
        }
        d.deserialize_map(V)
    }
}

/// A camera model and the values of its parameters, in the model's slice order.
#[derive(Debug, Clone, PartialEq)]
pub struct Intrinsics {
    /// The model.
    pub model: CameraModel,
    /// One value per parameter of the model, in its slice order.
    pub values: Vec<f64>,
}

impl Intrinsics {
    /// `values` of `model`; `None` when their number is not the model's.
    pub fn new(model: CameraModel, values: Vec<f64>) -> Option<Self> {
        (values.len() == keys(model).len()).then_some(Self { model, values })
    }

    /// The values of `table`'s keys, each of `model`'s parameters missing from it taken from
    /// `default` (its slice order). Keys that are not `model`'s are ignored here; the project
    /// file's check refuses them ([`Intrinsics::unknown_key`]).
    pub fn from_table(model: CameraModel, table: &KeyedValues, default: &[f64]) -> Self {
        let values = keys(model)
            .iter()
            .zip(default)
            .map(|(k, d)| table.get(k).unwrap_or(*d))
            .collect();
        Self { model, values }
    }

    /// The first key of `table` that is not one of `model`'s, with the keys it has.
    pub fn unknown_key(model: CameraModel, table: &KeyedValues) -> Option<String> {
        let ks = keys(model);
        table
            .0
            .iter()
            .find(|(k, _)| !ks.contains(&k.as_str()))
            .map(|(k, _)| {
                format!(
                    "'{k}' is not a parameter of model '{model}' (its keys: {})",
                    ks.join(", ")
                )
            })
    }

    /// The keys of its parameters in files.
    pub fn keys(&self) -> &'static [&'static str] {
        keys(self.model)
    }

    /// The value of the parameter whose file key is `key`.
    pub fn get(&self, key: &str) -> Option<f64> {
        self.keys()
            .iter()
            .position(|k| *k == key)
            .map(|i| self.values[i])
    }

    /// As a table (keys in slice order).
    pub fn to_table(&self) -> KeyedValues {
        KeyedValues(
            self.keys()
                .iter()
                .zip(&self.values)
                .map(|(k, v)| (k.to_string(), *v))
                .collect(),
        )
    }
}

/// Written as the table of its keys (the model is written beside it by whoever holds it).
impl Serialize for Intrinsics {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.values.len()))?;
        for (k, v) in self.keys().iter().zip(&self.values) {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_has_its_keys_and_a_table_round_trips() {
        for m in CameraModel::ALL {
            assert_eq!(keys(m).len(), m.parameter_names().len(), "{m}");
            let values: Vec<f64> = (0..keys(m).len()).map(|k| k as f64 + 0.5).collect();
            let i = Intrinsics::new(m, values.clone()).unwrap();
            let back = Intrinsics::from_table(m, &i.to_table(), &vec![0.0; values.len()]);
            assert_eq!(back, i);
            assert_eq!(i.get(keys(m)[1]), Some(1.5));
        }
        assert!(Intrinsics::new(CameraModel::OpenCv, vec![0.0; 10]).is_none());
    }

    #[test]
    fn missing_keys_take_the_default_and_unknown_ones_are_named() {
        let t = KeyedValues(vec![("fx".into(), 300.0), ("fy".into(), 301.0)]);
        let i = Intrinsics::from_table(
            CameraModel::DoubleSphere,
            &t,
            &[1.0, 1.0, 640.0, 400.0, -0.2, 0.5],
        );
        assert_eq!(i.values, [300.0, 301.0, 640.0, 400.0, -0.2, 0.5]);
        assert_eq!(Intrinsics::unknown_key(CameraModel::DoubleSphere, &t), None);
        let bad = KeyedValues(vec![("c_mm".into(), 2.0)]);
        let e = Intrinsics::unknown_key(CameraModel::KannalaBrandt, &bad).unwrap();
        assert!(
            e.contains("'c_mm'") && e.contains("fx, fy, cx, cy, k1, k2, k3, k4"),
            "{e}"
        );
    }
}
