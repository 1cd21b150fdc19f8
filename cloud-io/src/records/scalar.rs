//! The scalar types of PLY properties and PCD fields: their sizes, names, and how a value of
//! each is read from binary data or parsed from text.

/// A scalar type of a property/field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::I64 | Scalar::U64 | Scalar::F64 => 8,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "int8",
            Scalar::U8 => "uint8",
            Scalar::I16 => "int16",
            Scalar::U16 => "uint16",
            Scalar::I32 => "int32",
            Scalar::U32 => "uint32",
            Scalar::I64 => "int64",
            Scalar::U64 => "uint64",
            Scalar::F32 => "float32",
            Scalar::F64 => "float64",
        }
    }

    /// Reads the value from the first `size()` bytes of `b` (the caller checked the length).
    pub(super) fn read(self, b: &[u8], big_endian: bool) -> Option<f64> {
        macro_rules! get {
            ($t:ty, $n:literal) => {{
                let arr: [u8; $n] = b.get(..$n)?.try_into().ok()?;
                if big_endian {
                    <$t>::from_be_bytes(arr)
                } else {
                    <$t>::from_le_bytes(arr)
                }
            }};
        }
        Some(match self {
            Scalar::I8 => f64::from(get!(i8, 1)),
            Scalar::U8 => f64::from(get!(u8, 1)),
            Scalar::I16 => f64::from(get!(i16, 2)),
            Scalar::U16 => f64::from(get!(u16, 2)),
            Scalar::I32 => f64::from(get!(i32, 4)),
            Scalar::U32 => f64::from(get!(u32, 4)),
            Scalar::I64 => get!(i64, 8) as f64,
            Scalar::U64 => get!(u64, 8) as f64,
            Scalar::F32 => f64::from(get!(f32, 4)),
            Scalar::F64 => get!(f64, 8),
        })
    }

    /// Parses a text value of this type: an integer within the type's range, or for the float
    /// types any number `f64` parses (NaN and infinities included: the caller decides).
    pub(super) fn parse_text(self, token: &[u8]) -> Option<f64> {
        let t = std::str::from_utf8(token).ok()?;
        match self {
            Scalar::I8 => t.parse::<i8>().ok().map(f64::from),
            Scalar::U8 => t.parse::<u8>().ok().map(f64::from),
            Scalar::I16 => t.parse::<i16>().ok().map(f64::from),
            Scalar::U16 => t.parse::<u16>().ok().map(f64::from),
            Scalar::I32 => t.parse::<i32>().ok().map(f64::from),
            Scalar::U32 => t.parse::<u32>().ok().map(f64::from),
            Scalar::I64 => t.parse::<i64>().ok().map(|v| v as f64),
            Scalar::U64 => t.parse::<u64>().ok().map(|v| v as f64),
            Scalar::F32 | Scalar::F64 => t.parse::<f64>().ok(),
        }
    }

    /// What a text value of this type must look like, for errors.
    pub(super) fn text_expectation(self) -> &'static str {
        match self {
            Scalar::I8 => "int8 (an integer in -128 ..= 127)",
            Scalar::U8 => "uint8 (an integer in 0 ..= 255)",
            Scalar::I16 => "int16 (an integer in -32768 ..= 32767)",
            Scalar::U16 => "uint16 (an integer in 0 ..= 65535)",
            Scalar::I32 => "int32 (an integer in -2147483648 ..= 2147483647)",
            Scalar::U32 => "uint32 (an integer in 0 ..= 4294967295)",
            Scalar::I64 => "int64 (an integer in -9223372036854775808 ..= 9223372036854775807)",
            Scalar::U64 => "uint64 (an integer in 0 ..= 18446744073709551615)",
            Scalar::F32 => "float32 (a number)",
            Scalar::F64 => "float64 (a number)",
        }
    }

    /// What a list length of this type must look like, for errors.
    pub(super) fn length_expectation(self) -> &'static str {
        match self {
            Scalar::I8 => "list length (an int8 >= 0)",
            Scalar::I16 => "list length (an int16 >= 0)",
            Scalar::I32 => "list length (an int32 >= 0)",
            Scalar::I64 => "list length (an int64 >= 0)",
            Scalar::U8 => "list length (a uint8: 0 ..= 255)",
            Scalar::U16 => "list length (a uint16: 0 ..= 65535)",
            Scalar::U32 => "list length (a uint32: 0 ..= 4294967295)",
            Scalar::U64 => "list length (a uint64 >= 0)",
            Scalar::F32 | Scalar::F64 => "list length (an integer >= 0)",
        }
    }

    /// Reads a list length: an integer type holding a value >= 0.
    pub(super) fn read_count(self, b: &[u8], big_endian: bool) -> Option<u64> {
        if matches!(self, Scalar::F32 | Scalar::F64) {
            return None;
        }
        let v = self.read(b, big_endian)?;
        (v >= 0.0).then_some(v as u64)
    }
}
