//! Standard output that fails cleanly: a closed pipe or a full disk ends `lssi` with exit
//! code 1 and one line on stderr, never a panic (`println!` panics on a write error).
//! Every command prints through [`outln!`](crate::outln) and [`out!`](crate::out).

use std::fmt;
use std::io::{self, Write};

/// Writes to standard output; on an error ends the process (see the module docs).
pub fn write_out(args: fmt::Arguments<'_>) {
    let mut stdout = io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args) {
        fail(&e)
    }
}

/// Flushes standard output (at the end of `main`); on an error ends the process.
pub fn flush() {
    if let Err(e) = io::stdout().lock().flush() {
        fail(&e)
    }
}

/// Says that the output could not be written, and exits with code 1; a closed pipe ends
/// quietly with code 0.
pub fn fail(error: &io::Error) -> ! {
    // A closed pipe (`lssi … | head`) is the reader's choice: no message, and success, as
    // `set -o pipefail` scripts expect of a command whose reader has all it wanted.
    if error.kind() == io::ErrorKind::BrokenPipe {
        std::process::exit(0)
    }
    let _ = writeln!(io::stderr(), "lssi: cannot write the output: {error}.");
    std::process::exit(1)
}

/// `println!` that ends `lssi` cleanly when standard output cannot be written.
#[macro_export]
macro_rules! outln {
    () => {
        $crate::output::write_out(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::write_out(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` that ends `lssi` cleanly when standard output cannot be written.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::output::write_out(format_args!($($arg)*))
    };
}
