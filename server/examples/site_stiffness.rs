//! Prints the static probe stiffness of the default torso at the seed's five sites.
use echogym::envs::calibration_press::SITES;
use echogym::sim::torso::{ProbeFace, Torso, TorsoParams};

fn main() {
    let torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
    for (name, xy) in SITES {
        for depth in [0.005, 0.01, 0.015] {
            println!(
                "{name} {depth}: {:.1} N/m",
                torso.static_probe_stiffness(xy, depth)
            );
        }
    }
}
