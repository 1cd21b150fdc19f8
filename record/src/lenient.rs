//! Reading back the numbers JSON cannot hold. `serde_json` writes a NaN or an infinity as
//! `null` (JSON has no such numbers, and a viewer plots `null` as a gap); read back strictly, a
//! `null` where a number belongs refuses the whole message — one NaN from a faulty device made a
//! recording unreadable from that tick on. This deserializer reads such a `null` as NaN (the sign
//! of an infinity is lost) and is otherwise the strict one: a `null` for an `Option` is `None`.

use serde::de::{self, DeserializeOwned, DeserializeSeed, IntoDeserializer, MapAccess, SeqAccess};
use serde::forward_to_deserialize_any;
use serde_json::Value;

/// `data` (JSON) as a `T`, a `null` where a number belongs read as NaN.
pub fn from_slice<T: DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    // The strict reader first: it is the fast path, and every finite recording takes it.
    match serde_json::from_slice(data) {
        Ok(value) => Ok(value),
        Err(strict) => {
            let value: Value = serde_json::from_slice(data).map_err(|e| e.to_string())?;
            T::deserialize(Lenient(&value))
                .map_err(|e: serde_json::Error| format!("{strict} (and read leniently: {e})"))
        }
    }
}

/// A JSON value whose `null`s read as NaN where a number is expected.
struct Lenient<'a>(&'a Value);

impl<'de> de::Deserializer<'de> for Lenient<'de> {
    type Error = serde_json::Error;

    fn deserialize_any<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Array(items) => visitor.visit_seq(Items(items.iter())),
            Value::Object(map) => visitor.visit_map(Entries {
                entries: map.iter(),
                value: None,
            }),
            other => de::Deserializer::deserialize_any(other, visitor),
        }
    }

    fn deserialize_f64<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_f64(f64::NAN),
            other => de::Deserializer::deserialize_f64(other, visitor),
        }
    }

    fn deserialize_f32<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_f32(f32::NAN),
            other => de::Deserializer::deserialize_f32(other, visitor),
        }
    }

    fn deserialize_option<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, Self::Error> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            _ => visitor.visit_some(self),
        }
    }

    fn deserialize_enum<V: de::Visitor<'de>>(
        self,
        name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        // Enums read strictly (their payloads carry no measured numbers here).
        de::Deserializer::deserialize_enum(self.0, name, variants, visitor)
    }

    fn deserialize_newtype_struct<V: de::Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Self::Error> {
        visitor.visit_newtype_struct(self)
    }

    forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit
        unit_struct seq tuple tuple_struct map struct identifier ignored_any
    }
}

/// The items of an array, each lenient.
struct Items<'a>(std::slice::Iter<'a, Value>);

impl<'de> SeqAccess<'de> for Items<'de> {
    type Error = serde_json::Error;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Self::Error> {
        self.0
            .next()
            .map(|v| seed.deserialize(Lenient(v)))
            .transpose()
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.0.len())
    }
}

/// The entries of an object, each value lenient.
struct Entries<'a> {
    entries: serde_json::map::Iter<'a>,
    value: Option<&'a Value>,
}

impl<'de> MapAccess<'de> for Entries<'de> {
    type Error = serde_json::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Self::Error> {
        let Some((key, value)) = self.entries.next() else {
            return Ok(None);
        };
        self.value = Some(value);
        seed.deserialize(key.as_str().into_deserializer()).map(Some)
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, Self::Error> {
        let value = self
            .value
            .take()
            .ok_or_else(|| de::Error::custom("a value asked for before its key"))?;
        seed.deserialize(Lenient(value))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::schema::{OperatorTick, TelerobotTick};

    /// Before: a tick with a NaN (a faulty device's reading, caught by the safety layer) was
    /// written as `null` and refused on reading, and with it the rest of the recording.
    #[test]
    fn non_finite_numbers_read_back_as_nan_and_options_stay_none() {
        let tick = OperatorTick {
            device_position_m: [f64::NAN, 0.25, f64::INFINITY],
            force_rendered_n: [f64::NEG_INFINITY, -1.5, 2.0],
            proxy_m: None,
            remote_force_n: Some([f64::NAN, 1.0, 2.0]),
            ..OperatorTick::default()
        };
        let json = serde_json::to_vec(&tick).unwrap();
        assert!(
            serde_json::from_slice::<OperatorTick>(&json).is_err(),
            "strict refuses"
        );
        let back: OperatorTick = from_slice(&json).unwrap();
        assert!(back.device_position_m[0].is_nan() && back.device_position_m[2].is_nan());
        assert_eq!(back.device_position_m[1], 0.25);
        assert!(back.force_rendered_n[0].is_nan());
        assert_eq!(back.force_rendered_n[1..], [-1.5, 2.0]);
        assert_eq!(back.proxy_m, None);
        let remote = back.remote_force_n.unwrap();
        assert!(remote[0].is_nan() && remote[1..] == [1.0, 2.0]);
        // Everything else as written.
        let finite = OperatorTick {
            device_position_m: [0.0; 3],
            force_rendered_n: [0.0; 3],
            remote_force_n: None,
            ..back
        };
        assert_eq!(finite, OperatorTick::default());
    }

    #[test]
    fn every_message_type_reads_leniently_as_it_reads_strictly() {
        let tick = TelerobotTick {
            session: 7,
            true_in_contact: Some(true),
            force_on_tool_n: [1.0, -2.0, 3.5],
            ..TelerobotTick::default()
        };
        let json = serde_json::to_vec(&tick).unwrap();
        let value: Value = serde_json::from_slice(&json).unwrap();
        let lenient: TelerobotTick = serde::Deserialize::deserialize(Lenient(&value)).unwrap();
        assert_eq!(lenient, tick);
        // Malformed JSON is still an error, never a panic.
        assert!(from_slice::<TelerobotTick>(b"{\"session\": ").is_err());
        assert!(from_slice::<TelerobotTick>(b"{\"session\": \"seven\"}").is_err());
    }
}
