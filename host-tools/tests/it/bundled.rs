//! The `lssi` binary on the recording that ships in data/ and on a malformed file.

#[test]
fn the_bundled_recording_identifies_through_the_binary() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/paper-eq17.csv");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(["identify", file, "--omega", "2", "--json"])
        .output()
        .expect("runs lssi");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8_lossy(&output.stdout);
    for term in [
        "\"x\"",
        "\"v\"",
        "\"x^2\"",
        "\"x^3\"",
        "\"x^2*v\"",
        "\"cos(2t)\"",
    ] {
        assert!(text.contains(term), "{term} missing in {text}");
    }
}

#[test]
fn a_malformed_file_is_one_sentence_and_exit_code_2() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.csv");
    std::fs::write(&path, "t,x\n0,1\n0.1,abc\n").expect("write");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_lssi"))
        .args(["identify"])
        .arg(&path)
        .output()
        .expect("runs lssi");
    assert_eq!(output.status.code(), Some(2));
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(
        message.contains("bad.csv") && message.contains("line 3") && message.contains("'x'"),
        "{message}"
    );
}
