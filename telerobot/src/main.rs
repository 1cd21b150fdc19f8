fn main() {
    eprintln!("telerobot: not built yet");
    std::process::exit(2);
}
