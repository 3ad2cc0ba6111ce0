//! The embedding examples run and do what their docs say. `cargo test` builds examples next
//! to the test binaries, so this runs the freshly built one.

use std::path::PathBuf;
use std::process::Command;

fn example(name: &str) -> PathBuf {
    // target/<profile>/deps/<this test> -> target/<profile>/examples/<name>
    let exe = std::env::current_exe().unwrap();
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .unwrap()
        .join("examples");
    let path = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.exists(),
        "example {name} was not built at {}",
        path.display()
    );
    path
}

#[test]
fn custom_operation_is_hosted_described_and_driven_by_a_mission() {
    let out = Command::new(example("custom_operation")).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("name: \"collatz\""), "{stdout}");
    assert!(stdout.contains("outcome: Succeeded"), "{stdout}");
    // 97 reaches 1 after 118 steps
    assert!(stdout.contains("steps: Value(Int(118))"), "{stdout}");
}

#[test]
fn self_healing_rebinds_a_panicked_operation_and_the_mission_succeeds() {
    let out = Command::new(example("self_healing")).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("injected a panic into pump"), "{stdout}");
    assert!(stdout.contains("rebound pump:"), "{stdout}");
    assert!(
        stdout.contains("mission Succeeded with 1 rebind(s)"),
        "{stdout}"
    );
}

#[test]
fn embedding_hosts_its_own_operation_refuses_a_bad_value_and_heals_a_panic() {
    let out = Command::new(example("embedding")).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("pump 1.0.0 on plant: [\"litres\", \"rate\"]"),
        "{stdout}"
    );
    assert!(
        stdout.contains("refused: rate: 50 is out of range"),
        "{stdout}"
    );
    assert!(stdout.contains("healed: "), "{stdout}");
    // 40 litres at 2 per step, the restarted pump resuming at the last level logged
    assert!(
        stdout.contains("Succeeded: 20 levels, the last 40 l"),
        "{stdout}"
    );
}
