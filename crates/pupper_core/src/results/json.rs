//! JSON that keeps the sign of an infinity. serde_json writes every
//! non-finite number as `null`, so a loop margin of +inf ("no gain makes it
//! unstable") and -inf ("no gain is stable") read the same. Here a value
//! is serialized once into [`Doc`], which keeps every f64, and written out
//! as JSON with ±inf as the strings `"inf"` and `"-inf"` (the CLI's
//! `--json`), or as the tokens `Infinity` and `-Infinity` that Python's
//! json module reads as floats (the module's dicts). NaN stays `null`.

use serde::ser::{self, Serialize};

use crate::error::{Error, Result};

/// A serialized value with its floats as they were.
#[derive(Debug, Clone, PartialEq)]
pub enum Doc {
    Null,
    Bool(bool),
    Int(i64),
    Uint(u64),
    Float(f64),
    Text(String),
    List(Vec<Doc>),
    Map(Vec<(String, Doc)>),
}

/// `v` as [`Doc`].
pub fn doc<T: Serialize + ?Sized>(v: &T) -> Result<Doc> {
    v.serialize(ToDoc)
        .map_err(|e| Error::Internal(format!("json: {}", e.0)))
}

/// `v` as JSON for a person's tools: ±inf the strings "inf" and "-inf".
pub fn to_value<T: Serialize + ?Sized>(v: &T) -> Result<serde_json::Value> {
    Ok(doc(v)?.to_value())
}

/// `v` as JSON text for Python's json.loads: ±inf `Infinity`, `-Infinity`.
pub fn to_python_text<T: Serialize + ?Sized>(v: &T) -> Result<String> {
    let mut out = String::new();
    doc(v)?.write_python(&mut out)?;
    Ok(out)
}

impl Doc {
    fn to_value(&self) -> serde_json::Value {
        use serde_json::Value;
        match self {
            Doc::Null => Value::Null,
            Doc::Bool(b) => Value::Bool(*b),
            Doc::Int(i) => Value::from(*i),
            Doc::Uint(u) => Value::from(*u),
            Doc::Float(f) if f.is_infinite() => {
                Value::String(if *f > 0.0 { "inf" } else { "-inf" }.into())
            }
            Doc::Float(f) => Value::from(*f),
            Doc::Text(s) => Value::String(s.clone()),
            Doc::List(v) => Value::Array(v.iter().map(Doc::to_value).collect()),
            Doc::Map(m) => {
                Value::Object(m.iter().map(|(k, v)| (k.clone(), v.to_value())).collect())
            }
        }
    }

    /// As Python's `json.dumps(doc, indent=2)` writes it: ±inf and NaN the
    /// tokens `Infinity`, `-Infinity` and `NaN` that Python's json (and
    /// pupper's readers) take back as floats.
    pub fn write_python_pretty(&self, out: &mut String, depth: usize) -> Result<()> {
        let pad = |out: &mut String, d: usize| {
            out.push('\n');
            out.push_str(&"  ".repeat(d));
        };
        match self {
            Doc::Float(f) if f.is_nan() => out.push_str("NaN"),
            Doc::List(v) if !v.is_empty() => {
                out.push('[');
                for (i, x) in v.iter().enumerate() {
                    out.push_str(if i > 0 { "," } else { "" });
                    pad(out, depth + 1);
                    x.write_python_pretty(out, depth + 1)?;
                }
                pad(out, depth);
                out.push(']');
            }
            Doc::Map(m) if !m.is_empty() => {
                out.push('{');
                for (i, (k, x)) in m.iter().enumerate() {
                    out.push_str(if i > 0 { "," } else { "" });
                    pad(out, depth + 1);
                    out.push_str(
                        &serde_json::to_string(k)
                            .map_err(|e| Error::Internal(format!("json: {e}")))?,
                    );
                    out.push_str(": ");
                    x.write_python_pretty(out, depth + 1)?;
                }
                pad(out, depth);
                out.push('}');
            }
            other => other.write_python(out)?,
        }
        Ok(())
    }

    fn write_python(&self, out: &mut String) -> Result<()> {
        let quoted =
            |s: &str| serde_json::to_string(s).map_err(|e| Error::Internal(format!("json: {e}")));
        match self {
            Doc::Float(f) if f.is_infinite() => {
                out.push_str(if *f > 0.0 { "Infinity" } else { "-Infinity" })
            }
            Doc::List(v) => {
                out.push('[');
                for (i, x) in v.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    x.write_python(out)?;
                }
                out.push(']');
            }
            Doc::Map(m) => {
                out.push('{');
                for (i, (k, x)) in m.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    out.push_str(&quoted(k)?);
                    out.push(':');
                    x.write_python(out)?;
                }
                out.push('}');
            }
            other => out.push_str(&other.to_value().to_string()),
        }
        Ok(())
    }
}

/// Why a value could not be serialized.
#[derive(Debug)]
pub struct DocError(String);

impl std::fmt::Display for DocError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for DocError {}

impl ser::Error for DocError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        DocError(msg.to_string())
    }
}

struct ToDoc;

/// A list being serialized (a sequence, a tuple; a variant's under its name).
struct ListDoc(Vec<Doc>, Option<&'static str>);

/// A map being serialized (a map, a struct; a variant's under its name).
struct MapDoc(Vec<(String, Doc)>, Option<String>, Option<&'static str>);

type R = std::result::Result<Doc, DocError>;

fn tagged(variant: Option<&'static str>, d: Doc) -> Doc {
    match variant {
        Some(v) => Doc::Map(vec![(v.to_string(), d)]),
        None => d,
    }
}

impl ser::Serializer for ToDoc {
    type Ok = Doc;
    type Error = DocError;
    type SerializeSeq = ListDoc;
    type SerializeTuple = ListDoc;
    type SerializeTupleStruct = ListDoc;
    type SerializeTupleVariant = ListDoc;
    type SerializeMap = MapDoc;
    type SerializeStruct = MapDoc;
    type SerializeStructVariant = MapDoc;

    fn serialize_bool(self, v: bool) -> R {
        Ok(Doc::Bool(v))
    }
    fn serialize_i8(self, v: i8) -> R {
        Ok(Doc::Int(v.into()))
    }
    fn serialize_i16(self, v: i16) -> R {
        Ok(Doc::Int(v.into()))
    }
    fn serialize_i32(self, v: i32) -> R {
        Ok(Doc::Int(v.into()))
    }
    fn serialize_i64(self, v: i64) -> R {
        Ok(Doc::Int(v))
    }
    fn serialize_u8(self, v: u8) -> R {
        Ok(Doc::Uint(v.into()))
    }
    fn serialize_u16(self, v: u16) -> R {
        Ok(Doc::Uint(v.into()))
    }
    fn serialize_u32(self, v: u32) -> R {
        Ok(Doc::Uint(v.into()))
    }
    fn serialize_u64(self, v: u64) -> R {
        Ok(Doc::Uint(v))
    }
    fn serialize_f32(self, v: f32) -> R {
        Ok(Doc::Float(v.into()))
    }
    fn serialize_f64(self, v: f64) -> R {
        Ok(Doc::Float(v))
    }
    fn serialize_char(self, v: char) -> R {
        Ok(Doc::Text(v.to_string()))
    }
    fn serialize_str(self, v: &str) -> R {
        Ok(Doc::Text(v.to_string()))
    }
    fn serialize_bytes(self, v: &[u8]) -> R {
        Ok(Doc::List(
            v.iter().map(|b| Doc::Uint((*b).into())).collect(),
        ))
    }
    fn serialize_none(self) -> R {
        Ok(Doc::Null)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> R {
        v.serialize(self)
    }
    fn serialize_unit(self) -> R {
        Ok(Doc::Null)
    }
    fn serialize_unit_struct(self, _: &'static str) -> R {
        Ok(Doc::Null)
    }
    fn serialize_unit_variant(self, _: &'static str, _: u32, variant: &'static str) -> R {
        Ok(Doc::Text(variant.to_string()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &'static str, v: &T) -> R {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        v: &T,
    ) -> R {
        Ok(tagged(Some(variant), v.serialize(self)?))
    }
    fn serialize_seq(self, len: Option<usize>) -> std::result::Result<ListDoc, DocError> {
        Ok(ListDoc(Vec::with_capacity(len.unwrap_or(0)), None))
    }
    fn serialize_tuple(self, len: usize) -> std::result::Result<ListDoc, DocError> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(
        self,
        _: &'static str,
        len: usize,
    ) -> std::result::Result<ListDoc, DocError> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        len: usize,
    ) -> std::result::Result<ListDoc, DocError> {
        Ok(ListDoc(Vec::with_capacity(len), Some(variant)))
    }
    fn serialize_map(self, _: Option<usize>) -> std::result::Result<MapDoc, DocError> {
        Ok(MapDoc(Vec::new(), None, None))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> std::result::Result<MapDoc, DocError> {
        Ok(MapDoc(Vec::new(), None, None))
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> std::result::Result<MapDoc, DocError> {
        Ok(MapDoc(Vec::new(), None, Some(variant)))
    }
}

impl ListDoc {
    fn push<T: Serialize + ?Sized>(&mut self, v: &T) -> std::result::Result<(), DocError> {
        self.0.push(v.serialize(ToDoc)?);
        Ok(())
    }
    fn done(self) -> R {
        Ok(tagged(self.1, Doc::List(self.0)))
    }
}

macro_rules! list_doc {
    ($($t:ident :: $f:ident),*) => {$(
        impl ser::$t for ListDoc {
            type Ok = Doc;
            type Error = DocError;
            fn $f<T: Serialize + ?Sized>(&mut self, v: &T) -> std::result::Result<(), DocError> {
                self.push(v)
            }
            fn end(self) -> R {
                self.done()
            }
        }
    )*};
}
list_doc!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl ser::SerializeMap for MapDoc {
    type Ok = Doc;
    type Error = DocError;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> std::result::Result<(), DocError> {
        // JSON keys are text: a number key is written as its digits
        self.1 = Some(match k.serialize(ToDoc)? {
            Doc::Text(s) => s,
            other => other.to_value().to_string(),
        });
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(
        &mut self,
        v: &T,
    ) -> std::result::Result<(), DocError> {
        let key = self.1.take().unwrap_or_default();
        self.0.push((key, v.serialize(ToDoc)?));
        Ok(())
    }
    fn end(self) -> R {
        Ok(Doc::Map(self.0))
    }
}

macro_rules! struct_doc {
    ($($t:ident),*) => {$(
        impl ser::$t for MapDoc {
            type Ok = Doc;
            type Error = DocError;
            fn serialize_field<T: Serialize + ?Sized>(
                &mut self,
                key: &'static str,
                v: &T,
            ) -> std::result::Result<(), DocError> {
                self.0.push((key.to_string(), v.serialize(ToDoc)?));
                Ok(())
            }
            fn end(self) -> R {
                Ok(tagged(self.2, Doc::Map(self.0)))
            }
        }
    )*};
}
struct_doc!(SerializeStruct, SerializeStructVariant);

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Serialize)]
    struct Margins {
        name: &'static str,
        up: f64,
        down: f64,
        nan: f64,
        none: Option<f64>,
        #[serde(flatten)]
        inner: Inner,
    }

    #[derive(serde::Serialize)]
    struct Inner {
        gm: f64,
    }

    #[test]
    fn infinities_keep_their_sign_and_the_rest_is_serde_jsons() {
        let m = Margins {
            name: "inf",
            up: f64::INFINITY,
            down: f64::NEG_INFINITY,
            nan: f64::NAN,
            none: None,
            inner: Inner { gm: 1.5 },
        };
        let v = to_value(&m).unwrap();
        assert_eq!(
            v.to_string(),
            r#"{"name":"inf","up":"inf","down":"-inf","nan":null,"none":null,"gm":1.5}"#
        );
        assert_eq!(
            to_python_text(&m).unwrap(),
            r#"{"name":"inf","up":Infinity,"down":-Infinity,"nan":null,"none":null,"gm":1.5}"#
        );
        // finite values as serde_json writes them
        let plain = serde_json::json!({"a": [1, -2, 0.1, true, "x"], "b": {"3": null}});
        assert_eq!(to_value(&plain).unwrap(), plain);
    }
}
