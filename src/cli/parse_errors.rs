//! Argument-parser errors in the one-line form of every input error.

use crate::error::InputError;

/// An argument-parser error in the one-line form of every input error:
/// `<command line>: FIELD: what is wrong`, FIELD being the argument concerned.
pub fn clap_error(e: &clap::Error) -> InputError {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let context = |kind: ContextKind| -> Option<String> {
        match e.get(kind)? {
            ContextValue::String(s) => Some(s.clone()),
            ContextValue::Strings(v) => Some(v.join(", ")),
            ContextValue::StyledStr(s) => Some(s.to_string()),
            ContextValue::StyledStrs(v) => Some(
                v.iter()
                    .map(ToString::to_string)
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
            ContextValue::Number(n) => Some(n.to_string()),
            _ => None,
        }
    };
    // "--threads <THREADS>" → "--threads"; "<SCENE>" stays.
    let arg_name = |a: String| match a.split_whitespace().next() {
        Some(first) if first.starts_with('-') => first.to_string(),
        _ => a,
    };
    let value = context(ContextKind::InvalidValue).map(|v| crate::error::echo(&v));
    let (field, message) = match e.kind() {
        ErrorKind::InvalidValue | ErrorKind::ValueValidation => {
            let field =
                context(ContextKind::InvalidArg).map_or_else(|| "argument".into(), arg_name);
            let why = std::error::Error::source(e)
                .map(|s| format!(": {s}"))
                .unwrap_or_default();
            let valid = context(ContextKind::ValidValue)
                .map(|v| format!(" (possible values: {v})"))
                .unwrap_or_default();
            (
                field,
                format!("invalid value '{}'{why}{valid}", value.unwrap_or_default()),
            )
        }
        ErrorKind::UnknownArgument => {
            let arg = context(ContextKind::InvalidArg).unwrap_or_default();
            let hint = context(ContextKind::SuggestedArg)
                .map(|a| format!("; did you mean '{a}'?"))
                .unwrap_or_default();
            (
                crate::error::echo(&arg),
                format!("unexpected argument{hint} (see mufe help)"),
            )
        }
        ErrorKind::InvalidSubcommand => {
            let sub = context(ContextKind::InvalidSubcommand).unwrap_or_default();
            (
                "command".into(),
                format!(
                    "unknown command '{}'; use run, check, partition, validate or sand",
                    crate::error::echo(&sub)
                ),
            )
        }
        ErrorKind::MissingRequiredArgument => (
            context(ContextKind::InvalidArg).map_or_else(|| "argument".into(), arg_name),
            "required argument is missing (see mufe help)".into(),
        ),
        ErrorKind::MissingSubcommand | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => (
            "command".into(),
            "no command given; use run, check, partition, validate or sand (see mufe --help)"
                .into(),
        ),
        ErrorKind::ArgumentConflict => (
            context(ContextKind::InvalidArg).map_or_else(|| "argument".into(), arg_name),
            format!(
                "cannot be used with {}",
                context(ContextKind::PriorArg).unwrap_or_else(|| "another argument".into())
            ),
        ),
        ErrorKind::TooManyValues => (
            context(ContextKind::InvalidArg).map_or_else(|| "argument".into(), arg_name),
            format!(
                "given too often or with too many values{}",
                value.map(|v| format!(" ('{v}')")).unwrap_or_default()
            ),
        ),
        ErrorKind::InvalidUtf8 => ("argument".into(), "is not valid UTF-8".into()),
        _ => {
            // Anything else: clap's own words, on one line.
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .map(str::trim)
                .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
                .filter(|l| !l.is_empty())
                .collect();
            let joined = message.join(" ");
            (
                "argument".into(),
                joined
                    .strip_prefix("error: ")
                    .unwrap_or(&joined)
                    .to_string(),
            )
        }
    };
    InputError::new("<command line>", field, message)
}
