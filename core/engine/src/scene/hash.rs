//! Scene hash. (lead)
