//! `${name}` substitution into a launch file's strings.
//!
//! `${name}` is replaced by the var's value; `$${` stands for a literal `${` (so a shell
//! script in `args` can still say `$${HOME}`); any other `$` is left alone (`$HOME`, `$$`).

use std::collections::BTreeMap;

/// Why a string could not be substituted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SubstituteError {
    /// `${name}` where `name` is not a var.
    Unknown(String),
    /// A `${` with no `}` after it.
    Unclosed,
}

/// Replaces every `${name}` in `text` by `vars[name]`.
pub fn substitute(text: &str, vars: &BTreeMap<String, String>) -> Result<String, SubstituteError> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find('$') {
        out.push_str(&rest[..at]);
        let tail = &rest[at..];
        if let Some(after) = tail.strip_prefix("$${") {
            out.push_str("${");
            rest = after;
        } else if let Some(after) = tail.strip_prefix("${") {
            let end = after.find('}').ok_or(SubstituteError::Unclosed)?;
            let name = &after[..end];
            let value = vars.get(name);
            out.push_str(value.ok_or_else(|| SubstituteError::Unknown(name.to_string()))?);
            rest = &after[end + 1..];
        } else {
            out.push('$');
            rest = &tail[1..];
        }
    }
    out.push_str(rest);
    Ok(out)
}
