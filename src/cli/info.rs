//! `caustica info`: what a volume file holds (dims, type, spacing, orientation, range,
//! histogram, window), or the series of a DICOM folder.

use std::path::PathBuf;

use caustica::volume;

use crate::Result;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// A volume file, a DICOM folder, file or DICOMDIR, or a time-series pattern with '*'.
    input: PathBuf,
    /// DICOM: describe this series of several (its number in the listing, or its UID).
    #[arg(long)]
    series: Option<String>,
    /// Rows of the histogram sketch.
    #[arg(long, default_value_t = 16)]
    histogram_rows: usize,
}

pub fn info(args: &InfoArgs) -> Result<()> {
    let started = std::time::Instant::now();
    let pattern = args.input.to_string_lossy().contains('*');
    let loaded = if pattern {
        let series = volume::series::Series::from_pattern(&args.input)?;
        println!(
            "time series: {} frames (showing frame 0: {})",
            series.len(),
            series.frames[0].display()
        );
        series.open_frame(0)?
    } else {
        match volume::open_series(&args.input, args.series.as_deref()) {
            Err(volume::VolumeError::SeveralSeries { path, listing }) => {
                let series = volume::dicom::list_series(&path)?;
                println!("{}: {} DICOM series", path.display(), series.len());
                print!("{listing}");
                println!("describe one with --series N or --series UID (render and view take the same option)");
                return Ok(());
            }
            other => other?,
        }
    };
    let load_ms = started.elapsed().as_secs_f64() * 1e3;
    let v = &loaded.volume;
    let m = &loaded.meta;
    let h = &loaded.histogram;
    println!("file:        {}", args.input.display());
    println!("format:      {}", m.format);
    println!(
        "dims:        {} ({} voxels)",
        volume::dims_text(&v.dims),
        v.voxel_count()
    );
    println!(
        "scalar type: {}",
        m.scalar.map_or("unknown".to_string(), |s| s.to_string())
    );
    println!("spacing:     {} × {} × {}", v.spacing[0], v.spacing[1], v.spacing[2]);
    let e = v.extent();
    println!("extent:      {} × {} × {}", e[0], e[1], e[2]);
    println!("modality:    {}", m.modality.as_deref().unwrap_or("unknown"));
    match &m.patient {
        Some(p) => println!(
            "orientation: {} (x, y, z run {}; {}), origin ({:.1}, {:.1}, {:.1}) mm LPS{}",
            p.axis_codes(),
            p.axis_words(),
            p.source,
            p.origin.x,
            p.origin.y,
            p.origin.z,
            match p.obliquity_deg() {
                d if d > 0.5 => format!(", {d:.1}° oblique"),
                _ => String::new(),
            }
        ),
        None => println!("orientation: not in the file (axes shown as stored)"),
    }
    println!("units:       {}", m.units);
    println!("value range: [{}, {}]", v.value_range[0], v.value_range[1]);
    println!(
        "percentiles: 0.5% {}  50% {}  99.5% {}",
        h.tails[0],
        h.quantile(0.5),
        h.tails[1]
    );
    println!("window:      {:?} ({})", loaded.default_window(), loaded.window_rule());
    let tf = caustica::transfer::default_for(m, h, loaded.default_window());
    println!(
        "default transfer functions: {}",
        tf.name.as_deref().unwrap_or("automatic")
    );
    for note in &m.notes {
        println!("note:        {note}");
    }
    println!("load time:   {load_ms:.0} ms");
    println!("histogram ({} bins, log scale):", volume::histogram::HISTOGRAM_BINS);
    for line in h.summary(args.histogram_rows) {
        println!("  {line}");
    }
    Ok(())
}
