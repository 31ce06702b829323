//! `surftile-outside SPEC X Y`: opens SPEC (a bank file, a `.toml` or a preset name)
//! through `surftile::open` with seed 0 and the default spacing, and prints the sample
//! at (X, Y) as `surftile sample` does. Errors go to stderr with a non-zero exit.

use surftile::Surface;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Err(e) = run(&args) {
        eprintln!("surftile-outside: {e}");
        std::process::exit(1);
    }
}

fn run(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let [spec, x, y] = args else {
        return Err("usage: surftile-outside SPEC X Y".into());
    };
    let (x, y): (f64, f64) = (x.parse()?, y.parse()?);
    let surface = surftile::open(spec)?.surface(0)?;
    let mut v = vec![0.0f32; surface.channels()];
    surface.sample(x, y, &mut v);
    let text: Vec<String> = v.iter().map(|v| format!("{v}")).collect();
    println!("{}", text.join(" "));
    Ok(())
}
