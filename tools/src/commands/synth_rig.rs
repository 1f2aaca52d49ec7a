//! `scanatlas synth-rig OUT_DIR`: a synthetic capture (mesh, photos, COLMAP, Bundler).

use anyhow::Result;
use scanatlas_core::synth::Shape;
use scanatlas_core::synth::rig::{RigParams, generate_rig};

use crate::cli::{ShapeArg, SynthRigArgs};

pub fn run(args: &SynthRigArgs, quiet: bool) -> Result<()> {
    let p = RigParams {
        shape: match args.shape {
            ShapeArg::Blob => Shape::Blob,
            ShapeArg::Terrain => Shape::Terrain,
            ShapeArg::Torus => Shape::Torus,
            ShapeArg::Multi => Shape::Multi,
        },
        faces: args.faces,
        photos: args.photos,
        width: args.width,
        height: args.height,
        smooth_regions: args.smooth_regions,
        k1: args.k1,
        gain_spread: args.gain_spread,
        seed: args.seed,
    };
    let out = generate_rig(&p, &args.out_dir)?;
    if !quiet {
        eprintln!(
            "wrote {} ({} faces) and {} photos; cameras: {} (COLMAP text), {} (binary), {} (Bundler), {} (MeshLab)",
            out.mesh.display(),
            out.faces,
            out.photos,
            out.colmap_text.display(),
            out.colmap_binary.display(),
            out.bundler.display(),
            out.meshlab_project.display()
        );
    }
    Ok(())
}
