//! One Zenoh session declaring client liveliness tokens in a loop, as anyone who reaches
//! a server can: the server's resident memory (`ServerInfo::rss_bytes`) every 10 000
//! tokens, then after they are undeclared. docs/reliability.md ("Client tokens") records
//! its figures.
//!
//! Run beside a server: `cargo run --release -p arena-cli --example token_flood --
//! --connect tcp/127.0.0.1:7447 [TOKENS]` (default 50 000).

use std::time::Duration;

use arena_client::Client;
use arena_protocol::keys;
use arena_protocol::session::{ConnectionFlags, Role};
use clap::Parser;

#[derive(Debug, Parser)]
struct Args {
    #[command(flatten)]
    connection: ConnectionFlags,
    /// Tokens to declare.
    #[arg(default_value_t = 50_000)]
    tokens: usize,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let client = Client::connect(&args.connection).await?;
    let server = client.pick_server_within(Duration::from_secs(5)).await?;
    let rss = || async { client.server_info(&server).await.map(|info| info.rss_bytes as f64 / (1 << 20) as f64) };
    let session = zenoh::open(args.connection.zenoh_config(Role::Client).map_err(anyhow::Error::msg)?)
        .await
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    println!("| tokens | server RSS (MiB) |");
    println!("|---:|---:|");
    println!("| 0 | {:.1} |", rss().await?);
    let mut held = Vec::with_capacity(args.tokens);
    for k in 0..args.tokens {
        let key = keys::client_liveliness(&args.connection.prefix, &format!("{:032x}", rand::random::<u128>()))?;
        held.push(session.liveliness().declare_token(key).await.map_err(|e| anyhow::anyhow!("{e}"))?);
        if (k + 1) % 10_000 == 0 || k + 1 == args.tokens {
            tokio::time::sleep(Duration::from_secs(1)).await;
            println!("| {} | {:.1} |", k + 1, rss().await?);
        }
    }
    drop(held);
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    tokio::time::sleep(Duration::from_secs(15)).await;
    println!("| undeclared, 15 s later | {:.1} |", rss().await?);
    client.close().await?;
    Ok(())
}
