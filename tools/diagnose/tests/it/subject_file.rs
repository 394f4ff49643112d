//! The diagnosis's subject file (`Physics::subject_toml`) is read back by
//! exo-config's own reader, which validates it, with the values written in.

use crate::common;

use exo_config::Subject;
use exo_diagnose::Physics;

#[test]
fn the_fitted_subject_file_reads_back_with_every_experiments_k_and_h() {
    let mut p = Physics::from_plant(&common::default_plant(), &[1, 3]);
    // Subject B's experiments 1 and 3 (configs/subjects/B.toml, the
    // paper's Table III) and an inertia other than the plant's 0.11.
    p.k = [(1, 28.67), (3, 18.59)].into_iter().collect();
    p.h = [(1, 14.09), (3, 9.70)].into_iter().collect();
    p.m_h = 0.125;
    let dir = std::env::temp_dir().join(format!("exo-diagnose-subject-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let file = dir.join("diagnosed.toml");
    std::fs::write(&file, p.subject_toml("diagnosed")).expect("write the subject file");
    let s = Subject::from_file(&file);
    std::fs::remove_dir_all(&dir).ok();
    let s = s.expect("the written subject file is a valid subject file");
    assert_eq!(s.name, "diagnosed");
    assert_eq!(s.inertia_kg_m2, 0.125);
    assert_eq!(s.experiment.len(), 2);
    for (e, k, h) in [(1, 28.67, 14.09), (3, 18.59, 9.70)] {
        let x = s.get(e).unwrap_or_else(|| panic!("experiment {e} written"));
        assert_eq!(x.stiffness_nm_per_rad, k, "K_h of experiment {e}");
        assert_eq!(x.hysteretic_damping_nm_per_rad, h, "H_h of experiment {e}");
    }
}
