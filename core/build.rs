//! Generates the gRPC code of `proto/gaitsweep/v1` with a vendored protoc.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    // prost-build runs the protoc named by PROTOC.
    std::env::set_var("PROTOC", protoc);
    let out_dir = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../proto");
    let files =
        ["types.proto", "worker.proto", "client.proto"].map(|f| root.join("gaitsweep/v1").join(f));
    tonic_prost_build::configure()
        .file_descriptor_set_path(out_dir.join("gaitsweep_v1_descriptor.bin"))
        .btree_map(".")
        .compile_protos(&files, &[root.clone()])?;
    println!("cargo:rerun-if-changed={}", root.display());
    Ok(())
}
