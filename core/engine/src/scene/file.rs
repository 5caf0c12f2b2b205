//! The scene file. (lead)
