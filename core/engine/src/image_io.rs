//! Plain image files (relit images, textures, environments). HELPER B: implement.
