//! `benches/run envs` (imaging part): B-mode images/s on one core, printed as one JSON
//! object. The probe sits coupled on the torso's skin (every line formed, the worst
//! case) over three views: the midline (vessels, vertebra), the kidney, and the ribs
//! (shadows). 128 × 128 and 256 × 256 images, default settings otherwise.

use std::time::Instant;

use echogym::sim::torso::{ProbeFace, Torso, TorsoParams};
use echogym::sim::ultrasound::{Imager, ImagingFrame, UltrasoundConfig};
use serde_json::json;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str, default: f64| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let (seconds, repeats) = (arg("--seconds", 2.0), arg("--repeats", 3.0) as usize);
    let torso = Torso::new(TorsoParams::default(), ProbeFace::default()).unwrap();
    let top = torso.params().top_z();
    let views = [
        ([0.0, 0.0], [1.0, 0.0, 0.0]),
        ([-0.07, -0.07], [0.0, 1.0, 0.0]),
        ([0.0, 0.0835], [0.0, 1.0, 0.0]),
    ];
    let mut result = serde_json::Map::new();
    for size in [128usize, 256] {
        let config = UltrasoundConfig {
            lines: size,
            rows: size,
            ..UltrasoundConfig::default()
        };
        let mut imager = Imager::new(config, torso.params().size);
        let mut image = vec![0u8; size * size];
        let mut runs = Vec::new();
        for _ in 0..repeats {
            let start = Instant::now();
            let mut n = 0u64;
            while start.elapsed().as_secs_f64() < seconds {
                for (xy, lateral) in views {
                    let frame = ImagingFrame {
                        origin: [xy[0], xy[1], top],
                        lateral,
                        axis: [0.0, 0.0, -1.0],
                        half_width: 0.005,
                    };
                    imager.render(&torso, &frame, &mut image);
                }
                n += views.len() as u64;
            }
            runs.push(n as f64 / start.elapsed().as_secs_f64());
        }
        result.insert(
            format!("images_per_s_{size}"),
            json!({"median": median(runs.clone()), "runs": runs}),
        );
    }
    println!("{}", serde_json::Value::Object(result));
}
