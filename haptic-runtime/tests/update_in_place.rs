//! Contact updates written in place (`ContactStage::update_into`, as the real-time contact thread
//! writes into the buffer it publishes) are the updates `ContactStage::update` returns, whatever
//! the buffer held before: a free-space update written over one with contacts has none, and the
//! haptic stage takes it as no contact.

mod common;

use common::{BoxOnFloor, HALF_M, box_body, pressing_hand};
use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{LinearizedContact, Pose, QueryParams, ToolState, Vec3};
use haptic_dynamics::{LinearizedBackwardEuler, PenaltyModel, PenaltyParams};
use haptic_runtime::{ContactStage, ContactUpdate, PipelineBuilder, PipelineConfig};

fn stage() -> ContactStage<BoxOnFloor, PenaltyModel> {
    ContactStage::new(
        BoxOnFloor::new(HALF_M),
        PenaltyModel::new(PenaltyParams::default()).unwrap(),
        Clusterer::new(ClusterParams::default()).unwrap(),
        box_body(),
        QueryParams::new(1e-3, 0.0).unwrap(),
    )
}

fn box_at(height_m: f64, tilt_rad: f64) -> ToolState {
    let mut pose = Pose::from_position(Vec3::new(0.0, 0.0, height_m));
    pose.orientation = nalgebra::UnitQuaternion::from_euler_angles(tilt_rad, 0.0, 0.0);
    ToolState::at_rest(&pose)
}

#[test]
fn updates_written_in_place_are_the_updates_returned() {
    let (mut in_place, mut returned) = (stage(), stage());
    let pressed = box_at(HALF_M - 0.0005, 0.0);
    let tilted = box_at(HALF_M - 0.0002, 0.05);
    let free = box_at(HALF_M + 0.05, 0.0);
    let mut buffer = ContactUpdate::none();
    let mut counts = Vec::new();
    // Contacts, fewer contacts, free space, contacts again: each written over the last.
    for (k, tool) in [pressed, tilted, free, pressed].iter().enumerate() {
        let t = k as f64 * 1e-3;
        in_place.update_into(tool, t, &mut buffer).unwrap();
        let expected = returned.update(tool, t).unwrap();
        assert_eq!(buffer, expected, "update {k}");
        counts.push(buffer.model.contact_count);
    }
    assert!(counts[0] > counts[1] && counts[1] > 0, "{counts:?}");
    assert_eq!(counts[2], 0);
    assert_eq!(counts[3], counts[0]);

    // The haptic stage takes a free-space update received after one with contacts as none,
    // although the buffer's storage beyond the count still holds the old tangents.
    let (mut with_contacts, mut no_contact) = (ContactUpdate::none(), ContactUpdate::none());
    in_place
        .update_into(&pressed, 0.01, &mut with_contacts)
        .unwrap();
    no_contact.copy_from(&with_contacts);
    in_place.update_into(&free, 0.02, &mut no_contact).unwrap();
    assert!(no_contact.model.is_empty() && no_contact.broad_phase_only);
    assert_eq!(no_contact.model, LinearizedContact::none());
    let mut pipeline = PipelineBuilder::new(box_body(), free.pose())
        .integrator(LinearizedBackwardEuler)
        .backend(BoxOnFloor::new(HALF_M))
        .contact_model(PenaltyModel::new(PenaltyParams::default()).unwrap())
        .device(pressing_hand())
        .config(PipelineConfig::default())
        .build()
        .unwrap();
    let haptic = pipeline.haptic_mut();
    haptic.receive_contact(&with_contacts, 0.01);
    assert_eq!(haptic.forces().contact, with_contacts.model);
    haptic.receive_contact(&no_contact, 0.02);
    assert!(haptic.forces().contact.is_empty());
    assert_eq!(haptic.contact(), &no_contact);
}
