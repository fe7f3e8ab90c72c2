//! Builders that make large scenes in code, deterministically from a seed.
//!
//! * [`city()`]: a grid of blocks and streets, buildings with window-subdivided facades,
//!   instanced where shapes repeat, a tiled ground; reaches 10^6–10^7 triangles.
//! * [`boxfield()`]: 83,334 random boxes on a plane, the occlusion benchmark of record.
//! * [`scatter()`]: one mesh instanced N times with random transforms.
//! * [`city_with_traffic`]: the city with N vehicles driving its streets and tower cranes,
//!   moved by animations (the moving benchmark scene `city+traffic:N`).

mod boxfield;
mod city;
mod crane;
mod facade;
mod scatter;
mod traffic;

pub use boxfield::{boxfield, boxfield_queries, BoxfieldLayout, BoxfieldParams};
pub use city::{city, City, CityLayout, CityParams};
pub use scatter::{scatter, ScatterParams};
pub use traffic::{city_with_traffic, TrafficParams, LANE_OFFSET, MAX_VEHICLES};
