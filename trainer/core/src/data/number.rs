//! The one number reader of every layout and of `--follow`: a field as
//! a number, in every form a locale or a tool writes one ([`number`]).

/// Whether `c` is a minus sign as locales write one: U+2212 (minus),
/// U+2012 (figure dash), U+2013 (en dash), U+FE63 (small hyphen-minus),
/// U+FF0D (full-width hyphen-minus).
fn is_minus_like(c: char) -> bool {
    matches!(
        c,
        '\u{2212}' | '\u{2012}' | '\u{2013}' | '\u{FE63}' | '\u{FF0D}'
    )
}

/// Whether `c` groups a number's digits: a no-break space (U+00A0), a
/// thin space (U+2009), a narrow no-break space (U+202F), an apostrophe
/// (Swiss `1'234`).
fn is_group_separator(c: char) -> bool {
    matches!(c, '\u{A0}' | '\u{2009}' | '\u{202F}' | '\'')
}

/// A field as a number: the one number reader of every layout and of
/// `--follow`.
///
/// Read as Rust reads a float after these forms are made plain: a minus
/// sign as locales write it ([`is_minus_like`]) in the mantissa or the
/// exponent (`6,442E−2`); digit groups set off by a no-break, thin or
/// narrow space or an apostrophe (`1 234,5`); a decimal comma where a
/// field has one comma and no point (`0,25`; a comma-separated file
/// quotes such a field); where a field has both, the one written last is
/// the decimal mark and the other groups digits (`1.234,5`, `1,234.5`).
/// `+` before a number or its exponent, `e` or `E`, `NaN` (padding, read
/// as NaN) and `inf` are taken as Rust takes them. `None` where the field
/// is text.
pub fn number(field: &str) -> Option<f64> {
    let field = field.trim();
    if let Ok(v) = field.parse::<f64>() {
        return Some(v);
    }
    let mut plain = String::with_capacity(field.len());
    for c in field.chars() {
        if is_minus_like(c) {
            plain.push('-');
        } else if !is_group_separator(c) {
            plain.push(c);
        }
    }
    let (commas, points) = (plain.matches(',').count(), plain.matches('.').count());
    let plain = match (plain.rfind(','), plain.rfind('.')) {
        (Some(_), None) if commas == 1 => plain.replacen(',', ".", 1),
        (Some(c), Some(p)) if c > p && commas == 1 => plain.replace('.', "").replacen(',', ".", 1),
        (Some(c), Some(p)) if p > c && points == 1 => plain.replace(',', ""),
        _ => plain,
    };
    plain.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one number reader: every form a locale or tool writes, and
    /// text that is none. Golden values typed from the forms' meaning.
    #[test]
    fn numbers_in_every_written_form() {
        for (field, want) in [
            ("6,442E−2", 0.06442),
            ("−0,5", -0.5),
            ("\u{2012}1.5", -1.5),
            ("\u{2013}1.5e\u{2013}1", -0.15),
            ("\u{FE63}2", -2.0),
            ("\u{FF0D}2,5", -2.5),
            ("1e+3", 1000.0),
            ("+1,5E+2", 150.0),
            ("1\u{A0}234,5", 1234.5),
            ("1\u{2009}234.5", 1234.5),
            ("1\u{202F}234,5", 1234.5),
            ("1'234.5", 1234.5),
            ("1.234,5", 1234.5),
            ("1,234.5", 1234.5),
            ("9.969000006E-3", 0.009969000006),
            ("  0.25 ", 0.25),
        ] {
            assert_eq!(number(field), Some(want), "{field}");
        }
        assert!(number("NaN").unwrap().is_nan());
        for text in ["abc", "1,2,3", "1.2.3", "t", "", "−", "1,2.3,4"] {
            assert_eq!(number(text), None, "{text}");
        }
    }
}
