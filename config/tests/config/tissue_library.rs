//! The tissue library (`lopd scene new --tissue`) holds exactly the `abdomen` scene's values:
//! the scene is where they are argued and cited, the library is what new scenes get, and the two
//! must not drift apart.

use lop_config::{load_scene, resolve_scene, tissue, Integrator, NodeMass};
use lop_config::{tissue_names, MSD_CALIBRATION};
use lop_sim::lop::{CageDynamics, CageShape};

#[test]
fn library_matches_the_abdomen_scene() {
    let scene = load_scene(&resolve_scene("abdomen").unwrap()).unwrap();
    assert_eq!(scene.bodies.len(), 4);
    let text = std::fs::read_to_string(&scene.path).unwrap();
    for body in &scene.bodies {
        let t = tissue(&body.name).unwrap_or_else(|| panic!("no tissue {:?}", body.name));
        let fem = body.fem.as_ref().unwrap();
        assert_eq!(fem.young, t.young, "{}", t.name);
        assert_eq!(fem.poisson, t.poisson, "{}", t.name);
        assert_eq!(fem.density, t.density, "{}", t.name);
        assert_eq!(fem.damping, t.fem_damping, "{}", t.name);
        assert_eq!(fem.dt, t.dt, "{}", t.name);
        assert_eq!(body.importance, t.importance, "{}", t.name);
        assert_eq!(body.color, t.color, "{}", t.name);
        assert_eq!(body.heat, t.heat, "{}", t.name);
        let msd = body.msd.as_ref().unwrap();
        assert_eq!(msd.mass, NodeMass::Density(t.density), "{}", t.name);
        assert_eq!(msd.dt, t.dt, "{}", t.name);
        assert_eq!(msd.integrator, Integrator::ImplicitEuler, "{}", t.name);
        // k = c E l with the organ's mean edge length between 10 and 20 mm (the scene's
        // comment gives 10.9-19.4 mm); the exact edge lengths are checked in lop-scene.
        let l = msd.stiffness / (MSD_CALIBRATION * t.young);
        assert!((0.010..0.020).contains(&l), "{}: l = {l}", t.name);
        let gc = body.gc.as_ref().unwrap();
        assert_eq!(
            (gc.shape, gc.dynamics, gc.dt),
            (CageShape::Fitted, CageDynamics::Projected, Some(t.gc_dt)),
            "{}",
            t.name
        );
        // The library cites the scene's source for the organ: its first author and year.
        let cite = t.source.split(':').nth(1).unwrap().trim();
        let author_year = &cite[..cite.find(')').unwrap() + 1];
        let author = author_year.split(' ').next().unwrap();
        let year = &author_year[author_year.find('(').unwrap()..];
        assert!(
            text.contains(author) && text.contains(year),
            "{}: abdomen.toml does not cite {author_year}",
            t.name
        );
    }
    // Every library tissue is either in the scene or says it is not.
    for name in tissue_names() {
        let t = tissue(name).unwrap();
        assert!(
            scene.body(name).is_some() || t.source.contains("Not part of the abdomen scene"),
            "{name}"
        );
    }
    assert!(tissue("LIVER").is_some() && tissue("heart").is_none());
}
