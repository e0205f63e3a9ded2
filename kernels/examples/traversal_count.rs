//! A fixed, deterministic traversal workload for comparing two builds by instruction count,
//! where wall time is too noisy (a shared 2-core machine varies ±30 % between runs):
//!
//! ```sh
//! cargo build --release -p stereotrace-kernels --example traversal_count
//! valgrind --tool=cachegrind --cache-sim=no target/release/examples/traversal_count single
//! ```
//!
//! The modes are `build` (the BVH alone: subtract it from the others), `single` (80 000
//! closest-hit and 80 000 occlusion rays, one at a time) and `packet` (the same rays in
//! 8-lane packets). It prints the number of hits, which must not change between builds.

use glam::Vec3;
use stereotrace_kernels::bvh::{BuildQuality, Ray, Tri, TriangleBvh};
use stereotrace_kernels::simd::F32s;
use stereotrace_kernels::synth::Rng;
use stereotrace_kernels::traverse::{ALL_LANES, PacketHits, RayPacket};

const WIDTH: usize = 400;
const HEIGHT: usize = 200;

fn main() -> Result<(), String> {
    let mode = std::env::args().nth(1).ok_or("usage: traversal_count build|single|packet")?;
    // 60 000 triangles up to 1.5 units across, scattered through a 40-unit cube.
    let mut rng = Rng::new(1);
    let mut unit = || rng.next_f32();
    let tris: Vec<Tri> = (0..60_000)
        .map(|_| {
            let c = Vec3::new(unit(), unit(), unit()) * 40.0 - 20.0;
            [(); 3].map(|_| c + (Vec3::new(unit(), unit(), unit()) - 0.5) * 1.5)
        })
        .collect();
    let (bvh, _) = TriangleBvh::build(&tris, BuildQuality::Medium).map_err(|e| e.to_string())?;
    let eye = Vec3::new(0.0, 0.0, 30.0);
    let dir = |x: usize, y: usize| Vec3::new(x as f32 / WIDTH as f32 - 0.5, y as f32 / HEIGHT as f32 - 0.5, -1.0);
    let mut hits = 0u64;
    match mode.as_str() {
        "build" => {}
        "single" => {
            for y in 0..HEIGHT {
                for x in 0..WIDTH {
                    hits += u64::from(bvh.intersect(&Ray::new(eye, dir(x, y))).is_some());
                    hits += u64::from(bvh.occluded(&Ray::segment(eye, dir(x, y), 0.0, 20.0)));
                }
            }
        }
        "packet" => {
            for y in 0..HEIGHT {
                for x in (0..WIDTH).step_by(8) {
                    let rays: [Ray; 8] = core::array::from_fn(|i| Ray::new(eye, dir(x + i, y)));
                    let mut packet = RayPacket::from_rays(&rays);
                    let mut packet_hits = PacketHits::default();
                    hits += u64::from(bvh.intersect_packet(&packet, ALL_LANES, &mut packet_hits).count_ones());
                    packet.tmax = F32s::splat(20.0);
                    hits += u64::from(bvh.occluded_packet(&packet, ALL_LANES).count_ones());
                }
            }
        }
        other => return Err(format!("unknown mode {other}: build, single or packet")),
    }
    println!("{hits}");
    Ok(())
}
