//! The ros2msg schema text of a message: written from a field list
//! ([`schema_text`]) and read back ([`parse_ros2msg`]). The encoding
//! ([`crate::cdr`]) and the contract ([`crate::schema`]) both use it, and it
//! uses neither.

/// ros2msg text of a field list: one `type name` line per field.
pub fn schema_text(fields: &[(&str, &str)]) -> String {
    let mut s = String::new();
    for (name, ty) in fields {
        s.push_str(ty);
        s.push(' ');
        s.push_str(name);
        s.push('\n');
    }
    s
}

/// The `(type, name)` of every field of a ros2msg schema text, in order.
/// Comments (`# …`), blank lines, constants (`TYPE NAME=VALUE`) and default
/// values (a third token) are skipped; reading stops at the `===` line that
/// starts the definitions of nested types.
pub fn parse_ros2msg(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("===") {
            break;
        }
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() || line.contains('=') {
            continue;
        }
        let mut tok = line.split_whitespace();
        if let (Some(ty), Some(name)) = (tok.next(), tok.next()) {
            out.push((ty.to_string(), name.to_string()));
        }
    }
    out
}
