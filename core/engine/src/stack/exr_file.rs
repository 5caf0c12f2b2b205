//! The stack as one OpenEXR file. HELPER B: implement.
