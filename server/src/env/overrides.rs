//! Scenario overrides as a request carries them (`OptionValue`s by dotted key) turned
//! into the TOML values the scenario loader applies: one converter for the overrides of a
//! create and of a reset, so a key means the same at either.

use arena_protocol::OptionValue;

/// `value` as TOML. A string that is a TOML value (`"{ kind = \"idm\" }"`, `"[1, 2]"`) is
/// taken as that value, so tables and arrays can be overridden too; any other string is
/// a plain string.
pub fn to_toml(value: &OptionValue) -> toml::Value {
    match value {
        OptionValue::Bool(b) => toml::Value::Boolean(*b),
        OptionValue::Int(i) => toml::Value::Integer(*i),
        OptionValue::Float(f) => toml::Value::Float(*f),
        OptionValue::Str(s) => format!("v = {s}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(s.clone())),
    }
}

/// Every override of a request, converted.
pub fn converted(overrides: &[(String, OptionValue)]) -> Vec<(String, toml::Value)> {
    overrides.iter().map(|(key, value)| (key.clone(), to_toml(value))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strings_that_are_toml_values_are_those_values_and_others_stay_strings() {
        let array = toml::Value::Array(vec![toml::Value::Integer(1), toml::Value::Integer(2)]);
        assert_eq!(to_toml(&OptionValue::Str("[1, 2]".into())), array);
        assert_eq!(to_toml(&OptionValue::Str("aggressive".into())), toml::Value::String("aggressive".into()));
        assert_eq!(to_toml(&OptionValue::Str("\"quoted\"".into())), toml::Value::String("quoted".into()));
        assert_eq!(to_toml(&OptionValue::Float(1.5)), toml::Value::Float(1.5));
    }
}
