mod coordinates;
pub use coordinates::*;
mod data_structure;
pub use data_structure::*;
mod reader;
pub use reader::*;
mod transform;
pub use transform::*;
