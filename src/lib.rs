pub use sightline_scene as scene;
