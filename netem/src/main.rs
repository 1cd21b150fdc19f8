fn main() {
    eprintln!("netem: not built yet");
    std::process::exit(2);
}
