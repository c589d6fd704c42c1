pub struct GlobalCoord(pub glam::IVec3);
pub struct LocalCoord(pub glam::UVec3);
pub struct Index(pub u32);
