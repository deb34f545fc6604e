//! Rewrites a `.vol` file in another layout.
//!
//! ```text
//! cargo run --release -p raycaster --example convert_vol -- IN.vol OUT.vol [BRICK_SIDE]
//! ```
//! Without BRICK_SIDE the output is linear.

use raycaster::format::vol::{self, VolLayout};
use raycaster::storage::LoadMode;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: convert_vol IN.vol OUT.vol [BRICK_SIDE]");
        std::process::exit(2);
    }
    let layout = match args.get(2).map(|s| s.parse::<u8>()) {
        None => VolLayout::Linear,
        Some(Ok(side)) if side >= 2 => VolLayout::Bricked { side },
        Some(_) => {
            eprintln!("convert_vol: BRICK_SIDE must be 2..=255");
            std::process::exit(2);
        }
    };
    let result = vol::open(args[0].as_ref(), LoadMode::Map)
        .and_then(|v| vol::write(args[1].as_ref(), &v, layout));
    if let Err(e) = result {
        eprintln!("convert_vol: {e}");
        std::process::exit(1);
    }
}
