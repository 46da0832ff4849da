use super::*;

#[test]
fn the_shipped_models_read() {
    assert!(Model::from_text(SHIPPED_HEIGHT).is_ok());
    assert!(Model::from_text(SHIPPED_ROOF).is_ok());
}
