//! `vol_gen` command: see the library crate for everything it does.

fn main() -> std::process::ExitCode {
    vol_gen::main_entry()
}
