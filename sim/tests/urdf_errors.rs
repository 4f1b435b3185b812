//! URDF loading errors name the file, the element and what was expected.

use std::path::PathBuf;

use gaitsweep_sim::urdf::RobotModel;
use gaitsweep_sim::Preset;

const LEGS: [&str; 4] = ["LF", "RF", "LH", "RH"];

/// A hand-written quadruped: floating base, 12 revolute joints, 4 sphere feet.
fn urdf(edit: impl Fn(&str, &str) -> String) -> String {
    let inertial = r#"<inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;
    let mut s = format!(
        r#"<?xml version="1.0"?><robot name="hand"><link name="base">{inertial}<collision><geometry><box size="0.6 0.3 0.2"/></geometry></collision></link>"#
    );
    for leg in LEGS {
        for (j, parent, child, z) in [
            ("HAA", "base".to_string(), format!("{leg}_HIP"), 0.0),
            ("HFE", format!("{leg}_HIP"), format!("{leg}_THIGH"), 0.0),
            ("KFE", format!("{leg}_THIGH"), format!("{leg}_SHANK"), -0.25),
        ] {
            s += &format!("<link name=\"{child}\">{inertial}</link>");
            let joint = format!(
                r#"<joint name="{leg}_{j}" type="revolute"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 {z}" rpy="0 0 0"/><axis xyz="0 1 0"/><limit effort="50" velocity="10" lower="-3" upper="3"/></joint>"#
            );
            s += &edit(&format!("{leg}_{j}"), &joint);
        }
        let foot = format!(
            r#"<link name="{leg}_FOOT"><collision><geometry><sphere radius="0.02"/></geometry></collision></link><joint name="{leg}_FOOT_FIXED" type="fixed"><parent link="{leg}_SHANK"/><child link="{leg}_FOOT"/><origin xyz="0 0 -0.25" rpy="0 0 0"/></joint>"#
        );
        s += &edit(&format!("{leg}_FOOT"), &foot);
    }
    s + "</robot>"
}

fn load(text: &str) -> Result<RobotModel, String> {
    let preset = Preset::load("anymal").unwrap();
    RobotModel::from_str(&PathBuf::from("hand.urdf"), text, &preset).map_err(|e| e.to_string())
}

#[test]
fn a_well_formed_hand_written_quadruped_loads() {
    let m = load(&urdf(|_, s| s.to_string())).unwrap();
    assert_eq!((m.links.len(), m.joints.len(), m.feet.len()), (13, 12, 4));
    assert!((m.total_mass - 13.0).abs() < 1e-5);
}

#[test]
fn malformed_xml_names_the_file() {
    let e = load("<robot name=\"x\"><link name=\"base\">").unwrap_err();
    assert!(
        e.contains("hand.urdf") && e.contains("not a valid urdf"),
        "{e}"
    );
}

#[test]
fn a_missing_joint_is_named() {
    let e = load(&urdf(|name, s| {
        if name == "RH_KFE" {
            s.replace("RH_KFE", "RH_KNEE")
        } else {
            s.to_string()
        }
    }))
    .unwrap_err();
    assert!(e.contains("hand.urdf"), "{e}");
    assert!(e.contains("RH_KNEE") || e.contains("RH_KFE"), "{e}");
}

#[test]
fn an_extra_actuated_joint_is_refused() {
    let extra = r#"<link name="TAIL"><inertial><mass value="0.1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link><joint name="TAIL_J" type="revolute"><parent link="base"/><child link="TAIL"/><axis xyz="1 0 0"/><limit effort="5" velocity="5" lower="-1" upper="1"/></joint>"#;
    let e = load(&urdf(|name, s| {
        if name == "LF_HAA" {
            format!("{s}{extra}")
        } else {
            s.to_string()
        }
    }))
    .unwrap_err();
    assert!(
        e.contains("joint TAIL_J") && e.contains("not listed"),
        "{e}"
    );
}

#[test]
fn a_non_revolute_actuated_joint_is_refused() {
    let e = load(&urdf(|name, s| {
        if name == "LH_HFE" {
            s.replace("type=\"revolute\"", "type=\"prismatic\"")
        } else {
            s.to_string()
        }
    }))
    .unwrap_err();
    assert!(e.contains("joint LH_HFE") && e.contains("revolute"), "{e}");
}

#[test]
fn a_missing_foot_is_named() {
    let e = load(&urdf(|name, s| {
        if name == "RF_FOOT" {
            s.replace("RF_FOOT", "RF_TOE")
        } else {
            s.to_string()
        }
    }))
    .unwrap_err();
    assert!(e.contains("link RF_FOOT") && e.contains("foot"), "{e}");
}
