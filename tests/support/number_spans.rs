//! Byte ranges of the numbers in a text, for the fuzz tests that poison them (URDF and the
//! TOML and JSON formats).

/// Byte ranges of the numbers in `s`.
pub fn number_spans(s: &str) -> Vec<(usize, usize)> {
    let b = s.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && (b[i + 1].is_ascii_digit() || b[i + 1] == b'.'));
        if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric() && b[i - 1] != b'_') {
            let mut j = i + 1;
            while j < b.len() && (b[j].is_ascii_digit() || b"eE.-+".contains(&b[j])) {
                j += 1;
            }
            spans.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    spans
}
