//! Where in a scene file a key or an error is: a light scan of the text, good enough to
//! name the line in a message.

use crate::error::SceneProblem;

/// The line, key and problem of a TOML error (toml's own text is several lines with a
/// source excerpt).
pub(crate) fn toml_problem(text: &str, e: &toml::de::Error) -> (Option<usize>, Option<String>, SceneProblem) {
    let message = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    let Some(span) = e.span().filter(|s| !(s.start == 0 && s.end >= text.trim_end().len())) else {
        // About the whole document, e.g. a missing top-level table.
        return (None, None, SceneProblem::Toml { message, column: None });
    };
    let before = text.get(..span.start).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    let (table, key) = key_at(text, line);
    let key = match (table, key) {
        // An unknown key is named by the message; the table is what it lacks.
        (t, _) if message.starts_with("unknown field") => t,
        (Some(t), Some(k)) => Some(format!("{t}.{k}")),
        (t, k) => t.or(k),
    };
    (Some(line), key, SceneProblem::Toml { message, column: Some(column) })
}

/// The 1-based line where `key` (`[load].steps`, `[[fix]] #2.vertices`, `[mesh]`) is
/// written, found by a light scan of the text.
pub(crate) fn line_of_key(text: &str, key: &str) -> Option<usize> {
    let close = key.rfind(']')?;
    let header = &key[..=close];
    let (nth, field) = match key[close + 1..].split_once('.') {
        Some((n, f)) => (n, Some(f)),
        None => (&key[close + 1..], None),
    };
    let nth = match nth.trim().strip_prefix('#') {
        Some(k) => k.parse::<usize>().ok()?,
        None => 1,
    };
    let mut seen = 0;
    let mut inside = false;
    for (i, raw) in text.lines().enumerate() {
        let l = raw.split('#').next().unwrap_or("").trim();
        if l.starts_with('[') {
            inside = l == header && {
                seen += 1;
                seen == nth
            };
            if inside && field.is_none() {
                return Some(i + 1);
            }
        } else if inside
            && let Some(f) = field
            && l.split_once('=').is_some_and(|(k, _)| k.trim() == f)
        {
            return Some(i + 1);
        }
    }
    None
}

/// The table (`[load]`, `[[fix]] #2`) and the key whose value covers 1-based `line`,
/// found by a light scan of the text (good enough to name them in a message).
fn key_at(text: &str, line: usize) -> (Option<String>, Option<String>) {
    let (mut table, mut key) = (None, None);
    let mut arrays: std::collections::HashMap<String, usize> = Default::default();
    let mut depth = 0i64; // open brackets of a multi-line value
    for raw in text.lines().take(line) {
        let l = raw.split('#').next().unwrap_or("").trim();
        if depth > 0 {
            depth += bracket_balance(l);
            continue;
        }
        if let Some(name) = l.strip_prefix("[[").and_then(|r| r.strip_suffix("]]")) {
            let name = name.trim().to_string();
            let k = arrays.entry(name.clone()).or_insert(0);
            *k += 1;
            table = Some(format!("[[{name}]] #{k}"));
            key = None;
        } else if let Some(name) = l.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            table = Some(format!("[{}]", name.trim()));
            key = None;
        } else if let Some((k, v)) = l.split_once('=') {
            key = Some(k.trim().to_string());
            depth = bracket_balance(v).max(0);
        }
    }
    (table, key)
}

fn bracket_balance(s: &str) -> i64 {
    s.chars()
        .map(|c| {
            if c == '[' {
                1
            } else if c == ']' {
                -1
            } else {
                0
            }
        })
        .sum()
}
