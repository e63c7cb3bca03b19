//! The scenes compiled into the tool (`host/scenes/*.toml`): the defaults of `demo`,
//! `eval` and `tradeoff` are these, so a binary copied or installed anywhere runs them
//! without the source tree.

use super::{Error, Scene};
use std::path::Path;

/// Each built-in scene's name and TOML text.
pub const SCENES: &[(&str, &str)] = &[
    ("letters", include_str!("../../scenes/letters.toml")),
    ("spheres", include_str!("../../scenes/spheres.toml")),
    ("dots", include_str!("../../scenes/dots.toml")),
    ("lines", include_str!("../../scenes/lines.toml")),
    ("curves", include_str!("../../scenes/curves.toml")),
    ("textile", include_str!("../../scenes/textile.toml")),
    ("fabric", include_str!("../../scenes/fabric.toml")),
    ("screw", include_str!("../../scenes/screw.toml")),
    ("paperclip", include_str!("../../scenes/paperclip.toml")),
];

/// The built-in scene `name`.
pub fn scene(name: &str) -> Result<Scene, Error> {
    let (_, text) = SCENES
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| Error::Invalid(format!("no built-in scene is called {name:?}")))?;
    Scene::parse(text, name).map_err(|e| e.within(format_args!("in the built-in scene {name}")))
}

/// The scene file at `path`, or the built-in scene `name` without one.
pub fn scene_or(path: Option<&Path>, name: &str) -> Result<Scene, Error> {
    match path {
        Some(path) => Scene::load(path),
        None => scene(name),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_scene_parses_under_its_name() {
        for (name, _) in SCENES {
            let s = scene(name).unwrap();
            assert!(!s.name.is_empty(), "{name}");
        }
        assert!(matches!(scene("nothing"), Err(Error::Invalid(_))));
    }

    #[test]
    fn a_scene_file_s_errors_say_whose_fault_they_are() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("roll.toml");
        assert!(matches!(
            scene_or(Some(&path), "letters"),
            Err(Error::Read { .. })
        ));
        let (_, letters) = SCENES.iter().find(|(n, _)| *n == "letters").unwrap();
        let text = letters.replace("frames = 36", "frames = 0");
        std::fs::write(&path, text).unwrap();
        let e = scene_or(Some(&path), "letters").unwrap_err();
        assert!(matches!(e, Error::Invalid(_)), "{e:?}");
        assert!(e.to_string().starts_with("in scene file "), "{e}");
        assert!(e.to_string().contains("sensor.frames"), "{e}");
    }
}
