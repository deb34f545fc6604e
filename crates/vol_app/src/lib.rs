//! `vol_app` as a library: the built-in demo volume and the interactive
//! viewer, so that the binary and the UI tests share one implementation.
//! [`turntable`] renders orbiting movies for both `vol_app render
//! --turntable` and the viewer's export. The binary (`src/main.rs`) adds the command line and `vol_app render`.

pub mod demo;
pub mod turntable;
pub mod viewer;
