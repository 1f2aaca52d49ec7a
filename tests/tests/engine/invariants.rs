//! Invariants of the architecture that no unit test covers: the tool is headless (no window,
//! GL or display library anywhere in its dependency tree), and a multi-sheet run stays within a
//! memory bound well below its decoded pixels.

use std::path::{Path, PathBuf};

/// Crates that would tie scanatlas to a display, a window system or a GPU API: any of them in
/// `Cargo.lock` breaks the promise that the tool runs on a headless server.
const DISPLAY_CRATES: &[&str] = &[
    "winit",
    "glutin",
    "glium",
    "glow",
    "gl",
    "gl_generator",
    "khronos_api",
    "wgpu",
    "wgpu-core",
    "wgpu-hal",
    "ash",
    "vulkano",
    "metal",
    "x11",
    "x11-dl",
    "x11rb",
    "xcb",
    "wayland-client",
    "wayland-sys",
    "wayland-backend",
    "smithay-client-toolkit",
    "sdl2",
    "glfw",
    "raw-window-handle",
    "softbuffer",
    "minifb",
    "egui",
    "eframe",
    "bevy",
    "kiss3d",
    "three-d",
    "piston",
];

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("tests/ has a parent").to_path_buf()
}

/// The package names of every `[[package]]` entry of a `Cargo.lock`.
fn locked_packages(lock: &str) -> Vec<String> {
    lock.lines()
        .filter_map(|l| l.strip_prefix("name = \""))
        .filter_map(|rest| rest.strip_suffix('"'))
        .map(str::to_owned)
        .collect()
}

#[test]
fn no_display_or_gpu_library_enters_the_dependency_tree() {
    let path = workspace_root().join("Cargo.lock");
    let lock = std::fs::read_to_string(&path).expect("the workspace has a Cargo.lock");
    let packages = locked_packages(&lock);
    assert!(
        packages.iter().any(|p| p == "scanatlas-core"),
        "{} lists no scanatlas-core: not the workspace lock file?",
        path.display()
    );
    let found: Vec<&String> =
        packages.iter().filter(|p| DISPLAY_CRATES.contains(&p.as_str())).collect();
    assert!(found.is_empty(), "display, window or GPU crates in Cargo.lock: {found:?}");
}

#[test]
fn the_lock_file_parser_finds_a_display_crate() {
    let lock = "[[package]]\nname = \"winit\"\nversion = \"0.30.0\"\n";
    let packages = locked_packages(lock);
    assert_eq!(packages, ["winit"]);
    assert!(DISPLAY_CRATES.contains(&packages[0].as_str()));
}
