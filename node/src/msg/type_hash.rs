//! REP 2011 type hashes (`RIHS01_<sha256 hex>`), computed as `rosidl_generator_type_description`
//! does, so rmw_zenoh peers accept our publishers and subscribers as the same types.
//!
//! The hash is the SHA-256 of a JSON text describing the type and, sorted by name, every
//! type it references (transitively). Each type is `{"type_name": ..., "fields": [...]}`,
//! each field `{"name": ..., "type": {"type_id": ..., "capacity": ..., "string_capacity":
//! ..., "nested_type_name": ...}}` with the ids of `type_description_interfaces/FieldType`
//! (basic type id, +48 for a fixed array whose size is the capacity, +144 for an unbounded
//! sequence; 1 for a nested type). Default values and constants do not enter it. Python's
//! `json.dumps(separators=(", ", ": "))` layout is reproduced byte for byte.
//!
//! Definitions are `.msg` texts. `.msg` types map to IDL as rosidl does (`char` is `uint8`,
//! `byte` is `octet`); `Header` alone means `std_msgs/Header`, and a bare type name means the
//! package of the message. Bounded strings and sequences (`string<=N`, `T[<=N]`) are refused
//! with [`TypeHashError::Unsupported`]: nothing here uses them.

use sha2::{Digest, Sha256};
use std::collections::BTreeSet;
use std::fmt::Write;

/// Why a type hash could not be computed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TypeHashError {
    /// A referenced type has no definition.
    #[error("no definition for message type `{0}`")]
    UnknownType(String),
    /// A line of a definition is not `TYPE NAME [DEFAULT]` or a constant.
    #[error("bad line {line} in the definition of `{type_name}`: `{text}`")]
    BadLine {
        /// The type being parsed.
        type_name: String,
        /// Line number, 1-based.
        line: usize,
        /// The line.
        text: String,
    },
    /// A field type this implementation does not hash.
    #[error("unsupported field type `{ty}` in `{type_name}`")]
    Unsupported {
        /// The type being parsed.
        type_name: String,
        /// The field type.
        ty: String,
    },
}

/// One field of a type description.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Field {
    name: String,
    type_id: u32,
    capacity: u64,
    nested_type_name: String,
}

/// The `FieldType` id of a basic `.msg` type.
fn basic_type_id(ty: &str) -> Option<u32> {
    Some(match ty {
        "int8" => 2,
        "uint8" | "char" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        "wstring" => 18,
        _ => return None,
    })
}

/// `pkg/Type` -> `pkg/msg/Type`; `Header` -> `std_msgs/msg/Header`; `Type` -> in `package`.
fn nested_name(ty: &str, package: &str) -> String {
    match ty.split_once('/') {
        Some((pkg, name)) => format!("{pkg}/msg/{name}"),
        None if ty == "Header" => "std_msgs/msg/Header".to_owned(),
        None => format!("{package}/msg/{ty}"),
    }
}

/// The fields of `type_name` from its `.msg` text.
fn parse_fields(type_name: &str, text: &str) -> Result<Vec<Field>, TypeHashError> {
    let package = type_name.split('/').next().unwrap_or_default();
    let unsupported = |ty: &str| TypeHashError::Unsupported {
        type_name: type_name.to_owned(),
        ty: ty.to_owned(),
    };
    let mut fields = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or_default().trim();
        if line.is_empty() {
            continue;
        }
        let mut words = line.split_whitespace();
        let (Some(ty), Some(name)) = (words.next(), words.next()) else {
            return Err(TypeHashError::BadLine {
                type_name: type_name.to_owned(),
                line: i + 1,
                text: raw.to_owned(),
            });
        };
        if line[ty.len()..].contains('=') {
            continue; // a constant, `TYPE NAME=VALUE`
        }
        let (base, array) = match ty.split_once('[') {
            Some((base, rest)) => (
                base,
                Some(rest.strip_suffix(']').ok_or_else(|| unsupported(ty))?),
            ),
            None => (ty, None),
        };
        let (base_id, nested_type_name) = match basic_type_id(base) {
            Some(id) => (id, String::new()),
            None if base.contains('<') => return Err(unsupported(ty)),
            None => (1, nested_name(base, package)),
        };
        let (type_id, capacity) = match array {
            None => (base_id, 0),
            Some("") => (base_id + 144, 0),
            Some(n) => (base_id + 48, n.parse().map_err(|_| unsupported(ty))?),
        };
        fields.push(Field {
            name: name.to_owned(),
            type_id,
            capacity,
            nested_type_name,
        });
    }
    if fields.is_empty() {
        // rosidl gives an empty structure this one placeholder member.
        fields.push(Field {
            name: "structure_needs_at_least_one_member".to_owned(),
            type_id: 3,
            capacity: 0,
            nested_type_name: String::new(),
        });
    }
    Ok(fields)
}

/// The message types the fields of `type_name` (defined by the `.msg` text `text`) refer to,
/// as `pkg/msg/Type` names, each once, in field order: the direct dependencies that a
/// complete definition ([`super::schema`]) or a type description includes.
pub fn referenced_types(type_name: &str, text: &str) -> Result<Vec<String>, TypeHashError> {
    let mut names: Vec<String> = Vec::new();
    for field in parse_fields(type_name, text)? {
        if !field.nested_type_name.is_empty() && !names.contains(&field.nested_type_name) {
            names.push(field.nested_type_name);
        }
    }
    Ok(names)
}

/// Appends `{"type_name": ..., "fields": [...]}` in Python's `json.dumps` layout. Names are
/// ROS identifiers (ASCII letters, digits, `_` and `/`), which need no escaping.
fn write_type(out: &mut String, type_name: &str, fields: &[Field]) {
    let _ = write!(out, "{{\"type_name\": \"{type_name}\", \"fields\": [");
    for (i, f) in fields.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        let _ = write!(
            out,
            "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {}, \
             \"string_capacity\": 0, \"nested_type_name\": \"{}\"}}}}",
            f.name, f.type_id, f.capacity, f.nested_type_name
        );
    }
    out.push_str("]}");
}

/// The canonical JSON text REP 2011 hashes for `type_name`, whose definition and those of
/// the types it references come from `definition` (a `.msg` text per `pkg/msg/Type` name).
pub fn type_description_json<'a>(
    type_name: &str,
    definition: impl Fn(&str) -> Option<&'a str>,
) -> Result<String, TypeHashError> {
    let parse = |name: &str| {
        let text = definition(name).ok_or_else(|| TypeHashError::UnknownType(name.to_owned()))?;
        parse_fields(name, text)
    };
    let top = parse(type_name)?;
    let mut referenced = BTreeSet::new();
    let mut queue: Vec<String> = top.iter().map(|f| f.nested_type_name.clone()).collect();
    while let Some(name) = queue.pop() {
        if !name.is_empty() && referenced.insert(name.clone()) {
            queue.extend(parse(&name)?.into_iter().map(|f| f.nested_type_name));
        }
    }
    let mut out = String::from("{\"type_description\": ");
    write_type(&mut out, type_name, &top);
    out.push_str(", \"referenced_type_descriptions\": [");
    for (i, name) in referenced.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        write_type(&mut out, name, &parse(name)?);
    }
    out.push_str("]}");
    Ok(out)
}

/// The REP 2011 hash `RIHS01_<64 hex>` of `type_name` (see [`type_description_json`]).
pub fn rihs01<'a>(
    type_name: &str,
    definition: impl Fn(&str) -> Option<&'a str>,
) -> Result<String, TypeHashError> {
    let json = type_description_json(type_name, definition)?;
    let digest = Sha256::digest(json.as_bytes());
    let mut out = String::from("RIHS01_");
    for b in digest {
        let _ = write!(out, "{b:02x}");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_is_described_like_rosidl_does() {
        let json = type_description_json("builtin_interfaces/msg/Time", |_| {
            Some("int32 sec\nuint32 nanosec # comment\nint32 CONST=3\n")
        })
        .unwrap();
        assert_eq!(
            json,
            "{\"type_description\": {\"type_name\": \"builtin_interfaces/msg/Time\", \"fields\": \
             [{\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \"string_capacity\": \
             0, \"nested_type_name\": \"\"}}, {\"name\": \"nanosec\", \"type\": {\"type_id\": 7, \
             \"capacity\": 0, \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
             \"referenced_type_descriptions\": []}"
        );
    }

    #[test]
    fn arrays_sequences_and_bad_definitions() {
        let f = parse_fields("a/msg/B", "float64[9] k\nC[] cs\nuint8 x 5\n").unwrap();
        assert_eq!((f[0].type_id, f[0].capacity), (59, 9));
        assert_eq!(
            (f[1].type_id, f[1].nested_type_name.as_str()),
            (145, "a/msg/C")
        );
        assert_eq!(f[2].type_id, 3);
        assert!(matches!(
            parse_fields("a/msg/B", "string<=5 s"),
            Err(TypeHashError::Unsupported { .. })
        ));
        assert!(matches!(
            parse_fields("a/msg/B", "lonely"),
            Err(TypeHashError::BadLine { line: 1, .. })
        ));
        assert_eq!(
            rihs01("a/msg/B", |n| (n == "a/msg/B").then_some("C c")),
            Err(TypeHashError::UnknownType("a/msg/C".to_owned()))
        );
    }
}
