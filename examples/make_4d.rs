//! Writes the 4-D example volume of `septa hyper`: a blob that cools and
//! splits in two over time (the STEVE paper's fireball), as a 4-D NIfTI.
//!
//! ```sh
//! cargo run --release --example make_4d -- fireball.nii.gz [N] [FRAMES]
//! septa hyper fireball.nii.gz --iso 50 --times 0:5:0.5 -o fireball_out
//! ```
//!
//! N voxels per axis (default 40) at 1 mm, FRAMES frames (default 11) at
//! 0.5 s each; float32 samples, iso value 50 (`septa::hyper::fireball`).

use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first().map(PathBuf::from) else {
        eprintln!("usage: make_4d OUT.nii[.gz] [N] [FRAMES]");
        return ExitCode::from(2);
    };
    let parse = |i: usize, default: usize| -> Option<usize> {
        match args.get(i) {
            None => Some(default),
            Some(s) => s.parse().ok().filter(|&n| (4..=1000).contains(&n)),
        }
    };
    let (Some(n), Some(frames)) = (parse(1, 40), parse(2, 11)) else {
        eprintln!("N and FRAMES must be whole numbers from 4 to 1000");
        return ExitCode::from(2);
    };
    let image = septa::hyper::fireball::fireball(n, frames, 1.0, 0.5);
    match septa::io::nifti::write_image(&out, &image) {
        Ok(()) => {
            println!(
                "{}: {n} × {n} × {n} voxels × {frames} frames (0.5 s), iso {}",
                out.display(),
                septa::hyper::fireball::FIREBALL_ISO
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
