//! A scene built by hand through the application API (`docs/api.md`), rendered twice with one
//! instance moved between the frames: a checkered floor (a box), a can (a cylinder closed by a
//! disk) with a torus lying round its foot, a box with a cone on it, and a ball that rolls, lit by
//! a point light with shadows and an ambient light.
//!
//! ```text
//! cargo run --release --example api -- OUT_DIR     # writes OUT_DIR/frame-1.png and frame-2.png
//! ```
//!
//! Without `OUT_DIR` the frames go to a folder in the system's temporary directory. `cargo test`
//! renders the scene small and checks the two frames, so the example keeps up with the API.

use rtsl::runtime::api::{params, ApiError, Context, InstanceId};
use rtsl::runtime::glam::{Affine3A, Quat, Vec3};
use std::path::{Path, PathBuf};

const BALL_RADIUS: f32 = 0.6;
/// Where the ball is in each frame: it rolls towards the camera and to the right.
const BALL_AT: [Vec3; 2] = [Vec3::new(-0.3, BALL_RADIUS, 1.0), Vec3::new(0.9, BALL_RADIUS, 1.9)];

/// The ball's placement in `frame`, turned by the distance it rolled, as a ball rolls.
fn ball_transform(frame: usize) -> Affine3A {
    let travel = BALL_AT[frame] - BALL_AT[0];
    let axis = Vec3::Y.cross(travel).normalize_or_zero();
    let turn = Quat::from_axis_angle(if axis == Vec3::ZERO { Vec3::X } else { axis }, travel.length() / BALL_RADIUS);
    Affine3A::from_rotation_translation(turn, BALL_AT[frame])
}

/// Builds the scene in a new context; returns it with the ball's instance.
fn build_scene(width: u32, height: u32) -> Result<(Context, InstanceId), ApiError> {
    let mut rt = Context::new();
    rt.options.width = width;
    rt.options.height = height;
    rt.camera_look_at(Vec3::new(0.5, 3.0, 7.0), Vec3::new(0.0, 0.6, 0.0), Vec3::Y, 38.0);
    let checker = rt.find_shader("checker")?;
    let plastic = rt.find_shader("plastic")?;
    let metal = rt.find_shader("metal")?;

    // The floor: a thin slab whose top face carries 0..1 uvs, so `frequency` squares a side.
    let floor = rt.begin_object()?;
    rt.bind_shader(checker)?;
    rt.parameters(params!["frequency" => 6.0, "blackcolor" => [0.25, 0.25, 0.3], "whitecolor" => [0.85, 0.85, 0.8]])?;
    rt.box_mesh([-6.0, -0.1, -6.0], [6.0, 0.0, 6.0])?;
    rt.end_object()?;
    rt.instantiate_object(floor)?;

    // A can in two parts (one BVH, two materials). Quadrics sweep about z: stand them up.
    let can = rt.begin_object()?;
    rt.push_matrix();
    rt.rotate(-90.0, 1.0, 0.0, 0.0);
    rt.bind_shader(metal)?;
    rt.parameter("roughness", 0.15)?;
    rt.color(0.95, 0.75, 0.35);
    rt.cylinder(0.5, 0.0, 1.4)?;
    rt.disk(1.4, 0.5)?;
    rt.end_part()?;
    rt.bind_shader(plastic)?;
    rt.parameters(params!["Kd" => 0.7, "Ks" => 0.3])?;
    rt.color(0.8, 0.2, 0.15);
    rt.translate(0.0, 0.0, 0.15);
    rt.torus(0.65, 0.15)?;
    rt.pop_matrix()?;
    rt.end_object()?;
    rt.push_matrix();
    rt.translate(-1.8, 0.0, -0.6);
    rt.instantiate_object(can)?;
    rt.pop_matrix()?;

    let tower = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    rt.parameters(params!["Kd" => 0.6, "Ks" => 0.5, "roughness" => 0.08])?;
    rt.color(0.3, 0.7, 0.35);
    rt.box_mesh([-0.5, 0.0, -0.5], [0.5, 1.0, 0.5])?;
    rt.push_matrix();
    rt.translate(0.0, 1.0, 0.0);
    rt.rotate(-90.0, 1.0, 0.0, 0.0);
    rt.cone(1.0, 0.5)?;
    rt.pop_matrix()?;
    rt.end_object()?;
    rt.push_matrix();
    rt.translate(1.6, 0.0, -0.8);
    rt.rotate(30.0, 0.0, 1.0, 0.0);
    rt.instantiate_object(tower)?;
    rt.pop_matrix()?;

    let ball = rt.begin_object()?;
    rt.bind_shader(plastic)?;
    rt.parameters(params!["Kd" => 0.6, "Ks" => 0.6, "specularcolor" => [1.0, 0.95, 0.9]])?;
    rt.color(0.2, 0.4, 0.9);
    rt.sphere(BALL_RADIUS)?;
    rt.end_object()?;
    let ball_at = rt.instantiate_object(ball)?;
    rt.set_instance_transform(ball_at, ball_transform(0))?;

    let point = rt.find_shader("pointlight")?;
    let ambient = rt.find_shader("ambientlight")?;
    rt.light_source(point, params!["intensity" => 40.0, "from" => Vec3::new(3.0, 5.0, 4.0)])?;
    rt.light_source(ambient, params!["intensity" => 0.15])?;
    Ok((rt, ball_at))
}

/// Renders both frames of a `width` x `height` scene into `dir`; returns the files written.
fn render_frames(dir: &Path, width: u32, height: u32) -> anyhow::Result<[PathBuf; 2]> {
    let (mut rt, ball) = build_scene(width, height)?;
    let files = [dir.join("frame-1.png"), dir.join("frame-2.png")];
    for (frame, file) in files.iter().enumerate() {
        rt.set_instance_transform(ball, ball_transform(frame))?;
        let (image, report) = rt.render_frame()?;
        image.save(file)?;
        eprintln!("{}: {:.0} ms", file.display(), report.elapsed.as_secs_f64() * 1e3);
    }
    Ok(files)
}

fn main() -> anyhow::Result<()> {
    let dir = std::env::args_os().nth(1).map_or_else(|| std::env::temp_dir().join("rtsl-api-example"), PathBuf::from);
    std::fs::create_dir_all(&dir)?;
    for file in render_frames(&dir, 640, 480)? {
        println!("{}", file.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtsl::runtime::{diff_image, read_image};

    #[test]
    fn both_frames_are_written_and_only_the_ball_moves() {
        let dir = tempfile::tempdir().expect("temporary directory");
        let [first, second] = render_frames(dir.path(), 96, 72).expect("the scene renders");
        let a = read_image(&first).expect("frame 1 reads back");
        let b = read_image(&second).expect("frame 2 reads back");
        assert_eq!((a.width, a.height), (96, 72));
        assert!(a.pixels.chunks(4).filter(|p| p[0] + p[1] + p[2] > 0.05).count() > 96 * 72 / 2, "the frame is lit");
        let diff = diff_image(&a, &b).expect("same size");
        let moved = diff.differing_pixels(0.02);
        // The ball covers a few hundred pixels at this size; its shadow and the floor it uncovers
        // change too, the rest of the frame does not.
        assert!(moved > 50, "only {moved} pixels changed");
        assert!(moved < 96 * 72 / 4, "{moved} pixels changed: more than the ball moved");
    }
}
