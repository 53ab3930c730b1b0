//! Short fuzzing of the scene parser in the default test run: arbitrary text and mutated valid
//! scenes never panic, and every error says where the input is wrong: a parse error gives the
//! line, a value error names a field of the scene.

use std::path::Path;

use haptic_runtime::{Scene, SceneError};
use proptest::prelude::*;

const VALID: &str = include_str!("../../xtask/scenes/spoon-cup.toml");

/// Checks that `e`, the error for `text`, points at the place that is wrong.
fn error_locates_the_fault(e: &SceneError, text: &str) -> Result<(), TestCaseError> {
    match e {
        SceneError::Parse(message) => prop_assert!(
            message.contains("line "),
            "a parse error without a line: {message}"
        ),
        SceneError::Invalid { field, .. } => {
            // A dotted path whose first segment is a key of the scene that was parsed.
            let top = field.split(['.', '[']).next().unwrap_or_default();
            prop_assert!(
                !top.is_empty() && text.contains(top),
                "field `{field}` is not a key of the scene"
            );
        }
        other => prop_assert!(false, "parsing text gave a non-parse error: {other}"),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,400}") {
        if let Err(e) = Scene::from_toml_str(&text, Path::new(".")) {
            error_locates_the_fault(&e, &text)?;
        }
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
            error_locates_the_fault(&e, &text)?;
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
