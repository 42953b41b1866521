//! Prints the chessboard corners pingcal finds in each image as JSON, for bench/boards:
//! `board_corners COLS ROWS IMAGE...` → `[{"image": NAME, "found": bool, "reason": …,
//! "corners": [[x, y, sigma], …] in id order}, …]`.

use pingcal_targets::board::{detect_chessboard, Chessboard};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(cols), Some(rows)) = (
        args.first().and_then(|a| a.parse().ok()),
        args.get(1).and_then(|a| a.parse().ok()),
    ) else {
        eprintln!("usage: board_corners COLS ROWS IMAGE...");
        std::process::exit(2);
    };
    let board = Chessboard {
        cols,
        rows,
        square_mm: 1.0,
    };
    let mut out = Vec::new();
    for path in &args[2..] {
        let name = Path::new(path)
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        let img = match pingcal_targets::load_image(Path::new(path)) {
            Ok(img) => img,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let t = std::time::Instant::now();
        let found = detect_chessboard(&img, &board);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        out.push(match found {
            Ok(d) => serde_json::json!({
                "image": name, "found": true, "ms": ms,
                "corners": d.corners.iter().map(|c| [c.uv[0], c.uv[1], c.sigma_px]).collect::<Vec<_>>(),
            }),
            Err(e) => serde_json::json!({"image": name, "found": false, "ms": ms, "reason": e.to_string()}),
        });
    }
    println!("{}", serde_json::Value::Array(out));
}
