//! Files the program writes (and reads): the bottom layer, on `std` only, usable by every layer
//! above it (volume's NIfTI writer, gpu's pipeline cache, the commands, the viewer).

pub mod write;
