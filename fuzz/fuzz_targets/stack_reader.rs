//! The stack readers (dense and tiled) on arbitrary bytes, including headers whose claims disagree with the
//! data (the seed corpus has such files): it must return an error or a stack, never panic,
//! abort or allocate what the header claims without the file holding it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::io::Write;

fuzz_target!(|data: &[u8]| {
    // The reader takes a path (it seeks and checks the file's length): one scratch file per
    // fuzzing process, on tmpfs when there is one.
    thread_local! {
        static PATH: std::path::PathBuf = {
            let dir = if std::path::Path::new("/dev/shm").is_dir() { "/dev/shm".into() } else { std::env::temp_dir() };
            dir.join(format!("relume-fuzz-stack-{}.exr", std::process::id()))
        };
    }
    PATH.with(|path| {
        let mut f = std::fs::File::create(path).expect("scratch file");
        f.write_all(data).expect("write scratch file");
        drop(f);
        if let Ok(stack) = relume_engine::stack::exr_file::read_stack(path) {
            // A stack that reads must also give its bases (the relighter's next step).
            let _ = relume_engine::stack::bases::StackBases::from_header(&stack.header);
        }
        let _ = relume_engine::stack::exr_file::read_stack_header(path);
        // The tiled reader (format 2 as stored, format 1 converted), and the CPU relighter
        // built on what it returns: a stack that reads must relight without a panic.
        if let Ok(tiled) = relume_engine::stack::tiled::file::read_tiled(path) {
            if let Ok(mut r) =
                relume_engine::relight::CpuRelighter::from_tiled(std::sync::Arc::new(tiled))
            {
                let coefs: Vec<Vec<relume_engine::Rgb>> = (0..r.editable_count())
                    .map(|k| vec![relume_engine::Rgb::ONE; r.basis_count(k)])
                    .collect();
                let _ = r.relight(&coefs);
            }
        }
    });
});
