//! The scenes compiled into the tool (`host/scenes/*.toml`): the defaults of `demo`,
//! `eval` and `tradeoff` are these, so a binary copied or installed anywhere runs them
//! without the source tree.

use super::Scene;
use anyhow::Context;
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
pub fn scene(name: &str) -> anyhow::Result<Scene> {
    let (_, text) = SCENES
        .iter()
        .find(|(n, _)| *n == name)
        .with_context(|| format!("no built-in scene is called {name:?}"))?;
    Scene::parse(text, name).with_context(|| format!("in the built-in scene {name}"))
}

/// The scene file at `path`, or the built-in scene `name` without one.
pub fn scene_or(path: Option<&Path>, name: &str) -> anyhow::Result<Scene> {
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
        assert!(scene("nothing").is_err());
    }
}
