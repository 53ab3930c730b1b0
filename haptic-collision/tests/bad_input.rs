//! Bad input to the format detection gives the right error variant.

use std::path::Path;

use haptic_collision::{MeshError, MeshFormat};

#[test]
fn unknown_extensions_are_rejected_by_name() {
    assert!(matches!(
        MeshFormat::from_path(Path::new("part.step")),
        Err(MeshError::UnsupportedFormat { .. })
    ));
    assert!(MeshFormat::from_path(Path::new("part")).is_err());
    assert_eq!(
        MeshFormat::from_path(Path::new("a/B.STL")).unwrap(),
        MeshFormat::Stl
    );
    assert_eq!(
        MeshFormat::from_path(Path::new("b.obj")).unwrap(),
        MeshFormat::Obj
    );
    assert_eq!(
        MeshFormat::from_path(Path::new("c.ply")).unwrap(),
        MeshFormat::Ply
    );
}
