//! Generates the gRPC code of `proto/gaitsweep/v1` with a vendored protoc.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    // prost-build runs the protoc named by PROTOC.
    std::env::set_var("PROTOC", protoc);
    let out_dir = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    // Read when the script runs, not baked in with env!: a build-script binary reused
    // through a shared target directory read (and watched) another checkout's protos, and
    // a proto edit here left a stale `pb`.
    let root = std::path::PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?).join("../proto");
    let files =
        ["types.proto", "worker.proto", "client.proto"].map(|f| root.join("gaitsweep/v1").join(f));
    tonic_prost_build::configure()
        .file_descriptor_set_path(out_dir.join("gaitsweep_v1_descriptor.bin"))
        .btree_map(".")
        .compile_protos(&files, std::slice::from_ref(&root))?;
    // Each file, not the directory: cargo did not rerun this script when a .proto in
    // `root` changed (a stale `pb` after a proto edit).
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    println!("cargo:rerun-if-changed=build.rs");
    Ok(())
}
