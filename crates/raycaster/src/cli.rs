//! What the workspace's programs (`vol_app`, `vol_gen`) do alike on the
//! command line (feature `clap`): an error is one line on stderr,
//! `PROGRAM: error: MESSAGE`; help and version go to stdout; a panic is one
//! line too, never a backtrace.

use std::fmt::Display;
use std::process::ExitCode;

/// Prints `program: error: message` on stderr, the message on one line.
pub fn print_error(program: &str, message: impl Display) {
    eprintln!("{program}: error: {}", one_line(&message.to_string()));
}

/// What to do with a failed `clap` parse: help or version is printed on
/// stdout (exit code 0, or 2 for help shown because arguments are missing);
/// anything else is one error line ending in `(see --help)`, exit code 2.
pub fn parse_failure(program: &str, e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => {
            let _ = e.print();
            ExitCode::SUCCESS
        }
        ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            let _ = e.print();
            ExitCode::from(2)
        }
        _ => {
            // clap's text up to its usage line, without its `error:` prefix.
            let text = e.render().to_string();
            let message: Vec<&str> = text
                .lines()
                .map(str::trim)
                .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
                .filter(|l| !l.is_empty())
                .map(|l| l.strip_prefix("error: ").unwrap_or(l))
                .collect();
            print_error(program, format_args!("{} (see --help)", message.join(" ")));
            ExitCode::from(2)
        }
    }
}

/// Makes any panic print one line, `program: internal error: MESSAGE
/// (FILE:LINE)`, instead of the default message and backtrace.
pub fn one_line_panics(program: &'static str) {
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<&str>()
            .copied()
            .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
            .unwrap_or("unknown panic");
        let at = info
            .location()
            .map(|l| format!(" ({}:{})", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("{program}: internal error: {}{at}", one_line(message));
    }));
}

/// The non-empty lines of `text`, trimmed, joined by spaces.
fn one_line(text: &str) -> String {
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    #[test]
    fn messages_become_one_line() {
        assert_eq!(super::one_line("a\n  b\n\nc "), "a b c");
    }
}
