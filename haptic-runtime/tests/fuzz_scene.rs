//! Short fuzzing of the scene parser in the default test run: arbitrary text and mutated valid
//! scenes never panic; an error names what is wrong.

use std::path::Path;

use haptic_runtime::Scene;
use proptest::prelude::*;

const VALID: &str = include_str!("../../xtask/scenes/spoon-cup.toml");

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,400}") {
        let _ = Scene::from_toml_str(&text, Path::new("."));
    }

    #[test]
    fn mutated_scenes_never_panic(
        flips in prop::collection::vec((any::<prop::sample::Index>(), prop::char::range(' ', '~')), 1..6),
    ) {
        let mut chars: Vec<char> = VALID.chars().collect();
        for (at, c) in flips {
            let i = at.index(chars.len());
            chars[i] = c;
        }
        let text: String = chars.into_iter().collect();
        if let Err(e) = Scene::from_toml_str(&text, Path::new(".")) {
            prop_assert!(!e.to_string().is_empty());
        }
    }
}

#[test]
fn a_bad_field_is_named() {
    let text = VALID.replace("mass_kg = 0.02", "mass_kg = -1.0");
    let e = Scene::from_toml_str(&text, Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("tool.mass_kg"), "{e}");
    let text = VALID.replace("clusters = 5", "clusterz = 5");
    let e = Scene::from_toml_str(&text, Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("clusterz"), "{e}");
}
