//! The live view speaks the Foxglove WebSocket protocol: a client subscribes to channels and
//! receives their messages, decimated for display; a viewer that never reads costs dropped
//! messages (counted), never a blocked recorder.
#![allow(clippy::unwrap_used)]

mod common;

use std::time::Duration;

use common::*;
use futures_util::{SinkExt as _, StreamExt as _};
use record::schema::{OperatorTick, topic};
use record::{Kind, Message, Recorder, RecorderConfig, Side, Timed};
use tokio_tungstenite::tungstenite::client::IntoClientRequest as _;
use tokio_tungstenite::tungstenite::{Message as Ws, http::HeaderValue};

type Client =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(addr: std::net::SocketAddr, subprotocol: &str) -> Result<Client, String> {
    let mut request = format!("ws://{addr}").into_client_request().unwrap();
    request.headers_mut().insert(
        "sec-websocket-protocol",
        HeaderValue::from_str(subprotocol).unwrap(),
    );
    let (ws, response) = tokio_tungstenite::connect_async(request)
        .await
        .map_err(|e| e.to_string())?;
    assert_eq!(
        response.headers()["sec-websocket-protocol"],
        subprotocol.split(',').next().unwrap().trim()
    );
    Ok(ws)
}

/// The next text message as JSON.
async fn next_json(ws: &mut Client) -> serde_json::Value {
    loop {
        match tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .unwrap()
            .unwrap()
            .unwrap()
        {
            Ws::Text(t) => return serde_json::from_str(t.as_str()).unwrap(),
            Ws::Binary(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
}

fn tick_batch(from: u64, to: u64) -> Vec<Timed> {
    (from..to)
        .map(|k| Timed {
            t_ns: k as i64 * 1_000_000,
            message: Message::OperatorTick(Box::new(operator_tick(k))),
        })
        .collect()
}

fn start_live() -> Recorder {
    Recorder::start(RecorderConfig {
        mcap: None,
        live: Some(([127, 0, 0, 1], 0).into()),
        kind: Kind::Operator,
        clock_origin_ns: 0,
    })
    .unwrap()
}

#[tokio::test]
async fn a_client_subscribes_and_receives_decimated_data() {
    let recorder = start_live();
    let addr = recorder.live_addr().unwrap();
    let sink = recorder.sink();
    // The run's first messages exist before the viewer comes.
    sink.send_one(0, Message::Run(Box::new(run_start(Side::Operator))));
    sink.send(tick_batch(0, 1));
    tokio::time::sleep(Duration::from_millis(100)).await;

    let mut ws = connect(addr, "foxglove.websocket.v1").await.unwrap();
    let info = next_json(&mut ws).await;
    assert_eq!(info["op"], "serverInfo");
    let mut channels = std::collections::HashMap::new();
    while !channels.contains_key(topic::SCENE) || !channels.contains_key(topic::OPERATOR_TICK) {
        let advert = next_json(&mut ws).await;
        assert_eq!(advert["op"], "advertise");
        for c in advert["channels"].as_array().unwrap() {
            channels.insert(c["topic"].as_str().unwrap().to_owned(), c.clone());
        }
    }
    let tick_channel = &channels[topic::OPERATOR_TICK];
    assert_eq!(tick_channel["encoding"], "json");
    assert_eq!(tick_channel["schemaEncoding"], "jsonschema");
    assert_eq!(tick_channel["schemaName"], "mmt.OperatorTick");
    let schema: serde_json::Value =
        serde_json::from_str(tick_channel["schema"].as_str().unwrap()).unwrap();
    assert!(
        schema["properties"]["force_device_n"].is_object(),
        "{schema}"
    );
    let scene_channel = &channels[topic::SCENE];
    assert_eq!(scene_channel["schemaName"], "foxglove.SceneUpdate");
    assert_eq!(scene_channel["schemaEncoding"], "protobuf");
    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [
        {"id": 7, "channelId": tick_channel["id"]},
        {"id": 8, "channelId": scene_channel["id"]},
    ]});
    ws.send(Ws::Text(subscribe.to_string().into()))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;

    // One second of 1 kHz ticks, in real time (batches of 10 every 10 ms, as a helper hands
    // them over).
    let producer = std::thread::spawn(move || {
        let start = std::time::Instant::now();
        for k in (1..1001).step_by(10) {
            sink.send(tick_batch(k, k + 10));
            let due = Duration::from_millis(k + 9);
            std::thread::sleep(due.saturating_sub(start.elapsed()));
        }
    });
    let (mut ticks, mut scenes) = (Vec::new(), 0);
    while ticks.last().is_none_or(|t: &OperatorTick| t.index < 990) {
        let m = tokio::time::timeout(Duration::from_secs(10), ws.next())
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        let Ws::Binary(b) = m else { continue };
        assert_eq!(b[0], 1, "message data opcode");
        let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
        let payload = &b[13..];
        match sub {
            7 => ticks.push(serde_json::from_slice::<OperatorTick>(payload).unwrap()),
            8 => scenes += 1,
            other => panic!("subscription {other}"),
        }
    }
    producer.join().unwrap();
    // Plots at 100 Hz out of 1 kHz: every 10th tick; the scene at 50 Hz. (A few fewer if the
    // recorder thread, delayed, takes two batches at once: the wall-time cap drops the second.)
    assert!((85..=101).contains(&ticks.len()), "{} ticks", ticks.len());
    assert!(ticks.windows(2).all(|w| w[1].index - w[0].index >= 10));
    assert!(ticks.iter().all(|t| *t == operator_tick(t.index)));
    assert!((40..=51).contains(&scenes), "{scenes} scenes");
    let report = recorder.finish().unwrap();
    let live = report.live.unwrap();
    assert_eq!((live.clients, live.dropped), (1, 0));
}

#[tokio::test]
async fn the_sdk_subprotocol_is_accepted_and_others_are_refused() {
    let recorder = start_live();
    let addr = recorder.live_addr().unwrap();
    let mut ws = connect(addr, "foxglove.sdk.v1").await.unwrap();
    assert_eq!(next_json(&mut ws).await["op"], "serverInfo");
    let e = connect(addr, "something.else").await.unwrap_err();
    assert!(e.contains("400"), "{e}");
    recorder.finish().unwrap();
}

/// A viewer subscribes to everything, then never reads again: its queue fills, messages for it
/// are dropped and counted, and the recorder writes every message to the file all the same.
#[tokio::test]
async fn a_stalled_viewer_costs_dropped_messages_not_a_blocked_recorder() {
    let path = std::env::temp_dir().join(format!("record-live-{}.mcap", std::process::id()));
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.clone()),
        live: Some(([127, 0, 0, 1], 0).into()),
        kind: Kind::Demo,
        clock_origin_ns: 0,
    })
    .unwrap();
    let sink = recorder.sink();
    for b in batches(1) {
        sink.send(b);
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    // A small receive buffer, so that what stalls is the viewer and not the kernel's autotuned
    // megabytes of socket buffer.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(16 << 10).unwrap();
    let stream = tokio_tungstenite::MaybeTlsStream::Plain(
        socket.connect(recorder.live_addr().unwrap()).await.unwrap(),
    );
    let mut request = format!("ws://{}", recorder.live_addr().unwrap())
        .into_client_request()
        .unwrap();
    request.headers_mut().insert(
        "sec-websocket-protocol",
        HeaderValue::from_static("foxglove.websocket.v1"),
    );
    let (mut ws, _) = tokio_tungstenite::client_async(request, stream)
        .await
        .unwrap();
    let _ = next_json(&mut ws).await;
    let advert = next_json(&mut ws).await;
    let subscriptions: Vec<_> = advert["channels"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(i, c)| serde_json::json!({"id": i, "channelId": c["id"]}))
        .collect();
    ws.send(Ws::Text(
        serde_json::json!({"op": "subscribe", "subscriptions": subscriptions})
            .to_string()
            .into(),
    ))
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    // From here on the viewer reads nothing. 60 s of a demo's messages, clouds included, at
    // twenty times real time (the live view sends at most at display rate in wall time, so
    // filling the viewer's queue and the socket's buffers takes seconds).
    let producer = std::thread::spawn(move || {
        let mut refused = 0;
        let start = std::time::Instant::now();
        for (i, batch) in batches(60_000).into_iter().enumerate() {
            while !sink.send(batch.clone()) {
                refused += 1;
                std::thread::sleep(Duration::from_millis(1));
            }
            // A batch is 20 ms of run.
            let due = Duration::from_millis(i as u64);
            std::thread::sleep(due.saturating_sub(start.elapsed()));
        }
        refused
    });
    let refused = tokio::task::spawn_blocking(move || producer.join().unwrap())
        .await
        .unwrap();
    let report = recorder.finish().unwrap();
    let live = report.live.unwrap();
    eprintln!("stalled viewer: {live:?}");
    assert!(live.dropped > 0, "{live:?}");
    let read = record::read(&path, &[topic::OPERATOR_TICK]).unwrap();
    assert_eq!(read.operator_ticks.len(), 1 + 60_000, "refused {refused}");
    drop(ws);
}

/// Before: the live view's rates were counted in the producers' clock only, so `mmt experiment
/// --live`, tens of times faster than real time, sent scenes at thousands per second of wall
/// time. Now the scene goes out at most at display rate in wall time, the plots at most at
/// twice their rate, however fast the run.
#[tokio::test]
async fn scenes_go_out_at_display_rate_in_wall_time_however_fast_the_run() {
    let recorder = start_live();
    let sink = recorder.sink();
    sink.send_one(0, Message::Run(Box::new(run_start(Side::Operator))));
    let mut ws = connect(recorder.live_addr().unwrap(), "foxglove.websocket.v1")
        .await
        .unwrap();
    let _ = next_json(&mut ws).await;
    sink.send(tick_batch(0, 1));
    let mut ids = std::collections::HashMap::new();
    while !ids.contains_key(topic::SCENE) || !ids.contains_key(topic::OPERATOR_TICK) {
        let advert = next_json(&mut ws).await;
        for c in advert["channels"].as_array().unwrap() {
            ids.insert(c["topic"].as_str().unwrap().to_owned(), c["id"].clone());
        }
    }
    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [
        {"id": 1, "channelId": ids[topic::OPERATOR_TICK]},
        {"id": 2, "channelId": ids[topic::SCENE]},
    ]});
    ws.send(Ws::Text(subscribe.to_string().into()))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(100)).await;
    // 40 s of 1 kHz ticks in about 2 s: twenty times real time, as an experiment runs.
    let started = std::time::Instant::now();
    let producer = std::thread::spawn(move || {
        let start = std::time::Instant::now();
        for (i, k) in (1..40_001).step_by(20).enumerate() {
            sink.send(tick_batch(k, k + 20));
            let due = Duration::from_millis(i as u64);
            std::thread::sleep(due.saturating_sub(start.elapsed()));
        }
    });
    let (mut ticks, mut scenes, mut last) = (0u32, 0u32, 0u64);
    let mut wall = 0.0;
    // Until nothing has come for half a second (the run's very last ticks may be capped away).
    loop {
        let Ok(Some(Ok(m))) = tokio::time::timeout(Duration::from_millis(500), ws.next()).await
        else {
            break;
        };
        wall = started.elapsed().as_secs_f64();
        let Ws::Binary(b) = m else { continue };
        match u32::from_le_bytes(b[1..5].try_into().unwrap()) {
            1 => {
                ticks += 1;
                last = serde_json::from_slice::<OperatorTick>(&b[13..])
                    .unwrap()
                    .index;
            }
            _ => scenes += 1,
        }
    }
    producer.join().unwrap();
    assert!(
        last >= 39_000,
        "the last second of ticks never came: {last}"
    );
    // At producer rates: 4,000 ticks and 2,000 scenes. In wall time: at most 200 and 60 a second.
    let scene_hz = f64::from(scenes) / wall;
    let tick_hz = f64::from(ticks) / wall;
    assert!(
        scene_hz <= 61.0 && scenes >= 20,
        "{scenes} scenes in {wall:.2} s"
    );
    assert!(
        tick_hz <= 201.0 && ticks >= 50,
        "{ticks} ticks in {wall:.2} s"
    );
    recorder.finish().unwrap();
}

/// Before: `/run` went out once, at the start: a viewer that came later never got the run's
/// description (the Python viewer counted none). The run's start and end are latched: a new
/// subscriber gets the last one at once.
#[tokio::test]
async fn a_late_viewer_gets_the_runs_start_when_it_subscribes() {
    let recorder = start_live();
    let sink = recorder.sink();
    sink.send_one(0, Message::Run(Box::new(run_start(Side::Operator))));
    sink.send(tick_batch(0, 100));
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut ws = connect(recorder.live_addr().unwrap(), "foxglove.websocket.v1")
        .await
        .unwrap();
    let _ = next_json(&mut ws).await;
    let advert = next_json(&mut ws).await;
    let run = advert["channels"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["topic"] == topic::RUN)
        .unwrap()["id"]
        .clone();
    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [
        {"id": 5, "channelId": run},
    ]});
    ws.send(Ws::Text(subscribe.to_string().into()))
        .await
        .unwrap();
    let got = loop {
        let m = tokio::time::timeout(Duration::from_secs(5), ws.next())
            .await
            .expect("the run's start never came")
            .unwrap()
            .unwrap();
        if let Ws::Binary(b) = m {
            assert_eq!(u32::from_le_bytes(b[1..5].try_into().unwrap()), 5);
            break serde_json::from_slice::<record::schema::RunStart>(&b[13..]).unwrap();
        }
    };
    assert_eq!(got, run_start(Side::Operator));
    recorder.finish().unwrap();
}
