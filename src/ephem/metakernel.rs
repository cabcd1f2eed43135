//! SPICE meta-kernels (`.tm`): the list of kernel files that `FURNSH` would load.
//!
//! The rules are those of the SPICE text-kernel format ("Kernel Required Reading", sections
//! "Text Kernel Specifications" and "Meta-kernels"):
//! - only text between `\begindata` and `\begintext` is data;
//! - an assignment is `NAME = value`, `NAME += value` (append) or a parenthesised list of values;
//!   strings are in single quotes, a doubled quote `''` is a quote inside a string, commas between
//!   values are optional;
//! - in `KERNELS_TO_LOAD`, a string ending in `+` continues in the next string;
//! - `$SYMBOL` in a file name is replaced by the `PATH_VALUES` entry whose `PATH_SYMBOLS` entry is
//!   `SYMBOL`.
//!
//! A relative file name is resolved as `FURNSH` does, against the working directory; when no file
//! is there, against the meta-kernel's own folder (which is what a meta-kernel written next to its
//! kernels means, and what SPICE users otherwise reach with a `PATH_VALUES = ( '.' )` edit).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest meta-kernel read, bytes: a meta-kernel is a short text file.
pub const MAX_META_KERNEL_BYTES: u64 = 1 << 20;

/// One value of a text-kernel assignment.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Text(String),
    Number(String),
}

/// The variables of a text kernel's data sections, in assignment order of their values.
fn parse_variables(text: &str) -> Result<HashMap<String, Vec<Value>>, String> {
    let mut vars: HashMap<String, Vec<Value>> = HashMap::new();
    let mut data = String::new();
    let mut in_data = false;
    for line in text.lines() {
        let trimmed = line.trim();
        if trimmed == "\\begindata" {
            in_data = true;
            continue;
        }
        if trimmed == "\\begintext" {
            in_data = false;
            continue;
        }
        if in_data {
            data.push_str(line);
            data.push('\n');
        }
    }
    let chars: Vec<char> = data.chars().collect();
    let mut i = 0;
    let skip_blank = |i: &mut usize| {
        while *i < chars.len() && (chars[*i].is_whitespace() || chars[*i] == ',') {
            *i += 1;
        }
    };
    loop {
        skip_blank(&mut i);
        if i >= chars.len() {
            break;
        }
        let start = i;
        while i < chars.len() && !chars[i].is_whitespace() && chars[i] != '=' && chars[i] != '+' {
            i += 1;
        }
        let name: String = chars[start..i].iter().collect();
        if name.is_empty() {
            return Err(format!(
                "unexpected '{}' where a variable name should be",
                chars[i]
            ));
        }
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        let append = if i + 1 < chars.len() && chars[i] == '+' && chars[i + 1] == '=' {
            i += 2;
            true
        } else if i < chars.len() && chars[i] == '=' {
            i += 1;
            false
        } else {
            return Err(format!("variable {name} has no '=' after its name"));
        };
        skip_blank(&mut i);
        let mut values = Vec::new();
        let list = i < chars.len() && chars[i] == '(';
        if list {
            i += 1;
        }
        loop {
            skip_blank(&mut i);
            if i >= chars.len() {
                if list {
                    return Err(format!("variable {name}: the list has no closing ')'"));
                }
                break;
            }
            if list && chars[i] == ')' {
                i += 1;
                break;
            }
            if chars[i] == '\'' {
                let mut s = String::new();
                i += 1;
                loop {
                    if i >= chars.len() {
                        return Err(format!("variable {name}: a string has no closing quote"));
                    }
                    if chars[i] == '\'' {
                        if i + 1 < chars.len() && chars[i + 1] == '\'' {
                            s.push('\'');
                            i += 2;
                            continue;
                        }
                        i += 1;
                        break;
                    }
                    if chars[i] == '\n' {
                        return Err(format!(
                            "variable {name}: a string runs past the end of its line"
                        ));
                    }
                    s.push(chars[i]);
                    i += 1;
                }
                values.push(Value::Text(s));
            } else {
                let start = i;
                while i < chars.len()
                    && !chars[i].is_whitespace()
                    && chars[i] != ','
                    && chars[i] != ')'
                {
                    i += 1;
                }
                values.push(Value::Number(chars[start..i].iter().collect()));
            }
            if !list {
                break;
            }
        }
        let entry = vars.entry(name).or_default();
        if !append {
            entry.clear();
        }
        entry.extend(values);
    }
    Ok(vars)
}

fn strings(vars: &HashMap<String, Vec<Value>>, name: &str) -> Result<Vec<String>, String> {
    vars.get(name)
        .map(|values| {
            values
                .iter()
                .map(|v| match v {
                    Value::Text(s) => Ok(s.clone()),
                    Value::Number(n) => Err(format!("{name} holds '{n}', not a quoted string")),
                })
                .collect()
        })
        .unwrap_or_else(|| Ok(Vec::new()))
}

/// The file names listed by a meta-kernel's `KERNELS_TO_LOAD`, with continuations joined and
/// path symbols substituted (not yet resolved against a folder).
pub fn kernels_to_load(text: &str) -> Result<Vec<String>, String> {
    let vars = parse_variables(text)?;
    if !vars.contains_key("KERNELS_TO_LOAD") {
        return Err("not a meta-kernel: no KERNELS_TO_LOAD in a \\begindata section".into());
    }
    let symbols = strings(&vars, "PATH_SYMBOLS")?;
    let values = strings(&vars, "PATH_VALUES")?;
    if symbols.len() != values.len() {
        return Err(format!(
            "PATH_SYMBOLS has {} entries but PATH_VALUES has {}",
            symbols.len(),
            values.len()
        ));
    }
    let mut joined = Vec::new();
    let mut pending = String::new();
    for s in strings(&vars, "KERNELS_TO_LOAD")? {
        let trimmed = s.trim_end();
        let piece = if pending.is_empty() {
            trimmed.trim_start()
        } else {
            trimmed
        };
        if let Some(head) = piece.strip_suffix('+') {
            pending.push_str(head);
            continue;
        }
        pending.push_str(piece);
        joined.push(std::mem::take(&mut pending));
    }
    if !pending.is_empty() {
        return Err("the last KERNELS_TO_LOAD entry ends with the continuation '+'".into());
    }
    joined
        .into_iter()
        .map(|name| substitute(&name, &symbols, &values))
        .collect()
}

/// Replaces every `$SYMBOL` by its path value.
fn substitute(name: &str, symbols: &[String], values: &[String]) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = name;
    while let Some(pos) = rest.find('$') {
        out.push_str(&rest[..pos]);
        let after = &rest[pos + 1..];
        let end = after
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(after.len());
        let symbol = &after[..end];
        let Some(k) = symbols.iter().position(|s| s == symbol) else {
            return Err(format!(
                "'{name}' uses ${symbol}, which PATH_SYMBOLS does not define"
            ));
        };
        out.push_str(&values[k]);
        rest = &after[end..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Resolves a listed file name: as given (absolute, or relative to the working directory as
/// `FURNSH` does), else relative to the meta-kernel's folder.
pub fn resolve(name: &str, meta_kernel: &Path) -> PathBuf {
    let given = PathBuf::from(name);
    if given.is_absolute() || given.exists() {
        return given;
    }
    match meta_kernel.parent() {
        Some(dir) if dir.join(&given).exists() => dir.join(given),
        _ => given,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symbols_continuations_and_appends() {
        let text = r"
KPL/MK
Comment text with KERNELS_TO_LOAD = ( 'ignored.bsp' ) outside data.
\begindata
   PATH_VALUES  = ( '/data/kernels', 'lsk' )
   PATH_SYMBOLS = ( 'KER', 'L' )
   KERNELS_TO_LOAD = ( '$KER/spk/de440+'
                       '_moon.bsp',
                       '$KER/$L/naif0012.tls' )
\begintext
More comments.
\begindata
   KERNELS_TO_LOAD += 'moon_080317.tf'
   OTHER = ( 1, 2.5D0 , 'x''y' )
";
        let files = kernels_to_load(text).unwrap();
        assert_eq!(
            files,
            vec![
                "/data/kernels/spk/de440_moon.bsp".to_string(),
                "/data/kernels/lsk/naif0012.tls".to_string(),
                "moon_080317.tf".to_string(),
            ]
        );
        let vars = parse_variables(text).unwrap();
        assert_eq!(
            vars["OTHER"],
            vec![
                Value::Number("1".into()),
                Value::Number("2.5D0".into()),
                Value::Text("x'y".into())
            ]
        );
    }

    #[test]
    fn bad_meta_kernels_are_refused_with_a_reason() {
        let cases = [
            ("\\begindata\nX = ( 'a' )\n", "not a meta-kernel"),
            (
                "\\begindata\nKERNELS_TO_LOAD = ( 'a.bsp' \n",
                "no closing ')'",
            ),
            ("\\begindata\nKERNELS_TO_LOAD = ( 'a.bsp )\n", "runs past"),
            (
                "\\begindata\nKERNELS_TO_LOAD = ( '$K/a.bsp' )\n",
                "PATH_SYMBOLS does not define",
            ),
            ("\\begindata\nKERNELS_TO_LOAD = ( 'a+' )\n", "continuation"),
            ("\\begindata\nKERNELS_TO_LOAD ( 'a' )\n", "no '='"),
            (
                "\\begindata\nPATH_SYMBOLS = ('A')\nKERNELS_TO_LOAD = ( 'a' )\n",
                "PATH_VALUES has 0",
            ),
            (
                "\\begindata\nKERNELS_TO_LOAD = ( 3 )\n",
                "not a quoted string",
            ),
        ];
        for (text, why) in cases {
            let err = kernels_to_load(text).unwrap_err();
            assert!(err.contains(why), "{text:?}: {err}");
        }
    }
}
