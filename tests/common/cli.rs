//! Running the celray binary in the CLI tests: in a scratch folder of its
//! own, on the software adapter unless CELRAY_ADAPTER says otherwise.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `celray ARGS` in `cwd`, not yet run.
pub fn command(args: &[&str], cwd: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_celray"));
    cmd.args(args).current_dir(cwd);
    if std::env::var_os("CELRAY_ADAPTER").is_none() {
        cmd.env("CELRAY_ADAPTER", "software");
    }
    cmd
}

/// `celray ARGS` in `cwd`, run to the end.
pub fn celray(args: &[&str], cwd: &Path) -> Output {
    command(args, cwd).output().expect("run celray")
}

/// An empty folder `group/name` under the test target's scratch space.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(group)
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
