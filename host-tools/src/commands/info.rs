//! `lssi info FILE.csv`: reads a recording as `lssi identify` would and says what is in it, or
//! why it cannot be used.

use std::path::PathBuf;

use clap::Args;

use crate::error::CliError;
use crate::recording::{ColumnNames, Recording};

/// Arguments of `lssi info`.
#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    /// The recording: CSV with a header row naming at least t and x.
    #[arg(value_name = "FILE.csv")]
    pub file: PathBuf,
    /// Which header names hold which quantity.
    #[command(flatten)]
    pub columns: ColumnNames,
}

/// Runs `lssi info`.
pub fn run(args: &InfoArgs) -> Result<(), CliError> {
    let recording = Recording::read(&args.file, &args.columns)?;
    crate::out!("{}", describe(&recording));
    Ok(())
}

/// A few lines describing `recording`: size, time span, columns, and non-finite values.
pub fn describe(recording: &Recording) -> String {
    let n = recording.len();
    let first = recording.t.first().copied().unwrap_or(f64::NAN);
    let last = recording.t.last().copied().unwrap_or(f64::NAN);
    let mut text = format!(
        "{}: {n} sample{}, t from {first} to {last} s",
        recording.path.display(),
        if n == 1 { "" } else { "s" }
    );
    if n > 1 {
        text.push_str(&format!(
            " (mean interval {} s)",
            (last - first) / (n - 1) as f64
        ));
    }
    text.push('\n');

    let c = &recording.columns;
    let optional = |name: &Option<String>| match name {
        Some(name) => format!("'{name}'"),
        None => "absent".to_owned(),
    };
    text.push_str(&format!(
        "columns: t = '{}', x = '{}', v = {}, u = {}\n",
        c.t,
        c.x,
        optional(&c.v),
        optional(&c.u)
    ));

    let non_finite = |values: &[f64]| values.iter().filter(|v| !v.is_finite()).count();
    let mut counts = vec![
        ("t", non_finite(&recording.t)),
        ("x", non_finite(&recording.x)),
    ];
    if let Some(v) = &recording.v {
        counts.push(("v", non_finite(v)));
    }
    if let Some(u) = &recording.u {
        counts.push(("u", non_finite(u)));
    }
    let counts: Vec<String> = counts
        .iter()
        .map(|(name, count)| format!("{name} {count}"))
        .collect();
    text.push_str(&format!("non-finite values: {}\n", counts.join(", ")));

    let backwards = recording.t.windows(2).filter(|w| w[1] <= w[0]).count();
    if backwards > 0 {
        text.push_str(&format!(
            "warning: t fails to increase at {backwards} row{}\n",
            if backwards == 1 { "" } else { "s" }
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::parse_csv;

    #[test]
    fn describes_a_small_recording() {
        let text = "t,x,v\n0,1,nan\n0.5,2,0\n0.5,inf,1\n";
        let recording = parse_csv("r.csv", text.as_bytes(), &ColumnNames::default()).unwrap();
        assert_eq!(
            describe(&recording),
            "r.csv: 3 samples, t from 0 to 0.5 s (mean interval 0.25 s)\n\
             columns: t = 't', x = 'x', v = 'v', u = absent\n\
             non-finite values: t 0, x 1, v 1\n\
             warning: t fails to increase at 1 row\n"
        );
    }
}
