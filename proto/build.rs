//! Generates the tonic/prost code for `tessera/v1/render.proto` with a vendored protoc,
//! so a fresh machine needs no system protobuf compiler.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let protoc = protoc_bin_vendored::protoc_bin_path()?;
    let out_dir = std::path::PathBuf::from(std::env::var("OUT_DIR")?);
    // prost-build finds protoc through this variable; the build script is single-threaded.
    unsafe { std::env::set_var("PROTOC", protoc) };
    tonic_prost_build::configure()
        .file_descriptor_set_path(out_dir.join("tessera_descriptor.bin"))
        .compile_protos(&["tessera/v1/render.proto"], &["."])?;
    println!("cargo:rerun-if-changed=tessera/v1/render.proto");
    Ok(())
}
