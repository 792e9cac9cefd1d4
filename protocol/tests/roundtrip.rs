//! Every message survives encode -> decode; the codec refuses what it must.

use arena_protocol::*;

fn sample_observation() -> Observation {
    Observation::Dict(vec![
        ("action_mask".into(), Tensor::new(vec![5], TensorData::I8(vec![1, 1, 0, 1, 0])).unwrap()),
        ("observation".into(), Tensor::new(vec![2, 2], TensorData::F32(vec![0.5, -0.25, 1.0, 0.0])).unwrap()),
    ])
}

fn specs() -> EnvSpecs {
    let space = Space::Box { low: vec![-1.0; 4], high: vec![1.0; 4], shape: vec![2, 2], dtype: DType::F32 };
    EnvSpecs {
        possible_agents: vec!["ego".into()],
        observation_spaces: vec![("ego".into(), space.clone())],
        action_spaces: vec![("ego".into(), Space::Discrete { n: 5, start: 0 })],
        state_space: Space::Dict(vec![("x".into(), space)]),
        dt: 0.1,
        max_cycles: 200,
        render_fps: 10,
        render_modes: vec![RenderMode::RgbArray, RenderMode::Ansi],
    }
}

fn step_reply() -> StepReply {
    StepReply {
        seq: 3,
        observations: vec![("ego".into(), sample_observation())],
        rewards: vec![("ego".into(), -1.5)],
        terminations: vec![("ego".into(), false)],
        truncations: vec![("ego".into(), true)],
        infos: vec![(
            "ego".into(),
            Info { values: vec![("cost".into(), InfoValue::F64(2.0)), ("lane".into(), InfoValue::I64(1))] },
        )],
        agents: vec![],
    }
}

fn requests() -> Vec<RequestBody> {
    let env = EnvId(0xdead_beef_u128 << 64 | 7);
    vec![
        RequestBody::ServerInfo,
        RequestBody::CreateEnv {
            scenario: ScenarioSource::Named("merge".into()),
            options: CreateOptions {
                overrides: vec![
                    ("vehicle.ac.speed".into(), OptionValue::Float(18.0)),
                    ("x".into(), OptionValue::Str("y".into())),
                ],
                action_type: Some(ActionType::Continuous),
                observation: Some(ObservationKind::KinematicsWithMask),
                max_cycles: Some(9),
                render_size: Some((10, 20)),
                expert: Some(ExpertGame::Stackelberg),
            },
        },
        RequestBody::CreateEnv {
            scenario: ScenarioSource::Inline { file_name: "a.toml".into(), text: "name = 'a'".into() },
            options: CreateOptions::default(),
        },
        RequestBody::Reset {
            env,
            seq: 1,
            seed: Some(42),
            options: vec![("k".into(), OptionValue::Bool(true)), ("i".into(), OptionValue::Int(-3))],
        },
        RequestBody::Step {
            env,
            seq: 2,
            actions: vec![("ego".into(), Action::Meta(META_FASTER)), ("b".into(), Action::Continuous([0.5, -1.0]))],
        },
        RequestBody::StepBatch { steps: vec![BatchStep { env, seq: 4, actions: vec![] }] },
        RequestBody::Render { env, mode: RenderMode::RgbArray },
        RequestBody::State { env },
        RequestBody::Specs { env },
        RequestBody::Close { env },
    ]
}

fn replies() -> Vec<ReplyBody> {
    let error = ErrorReply { code: ErrorCode::InvalidAction, message: "component 0".into(), env_usable: true };
    vec![
        ReplyBody::ServerInfo(ServerInfo {
            server_id: "s".into(),
            version: "0.1.0".into(),
            protocol: 1,
            scenarios: vec!["merge".into()],
            envs: 2,
            max_envs: 9,
        }),
        ReplyBody::Created { env: EnvId(5), specs: specs() },
        ReplyBody::Reset(ResetReply {
            seq: 1,
            observations: vec![("ego".into(), sample_observation())],
            infos: vec![("ego".into(), Info::default())],
        }),
        ReplyBody::Step(step_reply()),
        ReplyBody::StepBatch(vec![BatchItem::Ok(step_reply()), BatchItem::Err(error.clone())]),
        ReplyBody::Render(Frame::Rgb { height: 1, width: 2, pixels: vec![1, 2, 3, 4, 5, 6] }),
        ReplyBody::Render(Frame::Ansi("..@..".into())),
        ReplyBody::State(sample_observation()),
        ReplyBody::Specs(specs()),
        ReplyBody::Closed,
        ReplyBody::Error(error),
    ]
}

#[test]
fn every_request_and_reply_round_trips_and_leads_with_its_version() {
    for body in requests() {
        let request = Request { version: PROTOCOL_VERSION, client: ClientId(u128::MAX), body };
        let bytes = encode(&request);
        assert_eq!(decode::<Request>(&bytes).unwrap(), request);
        assert_eq!(peek_version(&bytes), Some(PROTOCOL_VERSION));
    }
    for body in replies() {
        let reply = Reply { version: PROTOCOL_VERSION, body };
        let bytes = encode(&reply);
        assert_eq!(decode::<Reply>(&bytes).unwrap(), reply);
        assert_eq!(peek_version(&bytes), Some(PROTOCOL_VERSION));
    }
}

#[test]
fn the_codec_refuses_truncated_trailing_oversized_and_garbage_bytes() {
    let bytes = encode(&Request { version: 1, client: ClientId(3), body: requests().remove(4) });
    assert!(matches!(decode::<Request>(&bytes[..bytes.len() - 1]), Err(DecodeError::Invalid(_))));
    let mut longer = bytes.clone();
    longer.push(0);
    assert_eq!(decode::<Request>(&longer), Err(DecodeError::TrailingBytes { used: bytes.len(), len: bytes.len() + 1 }));
    let huge = vec![0u8; MAX_MESSAGE_BYTES + 1];
    assert_eq!(decode::<Request>(&huge), Err(DecodeError::TooLarge { len: MAX_MESSAGE_BYTES + 1 }));
    assert!(decode::<Request>(b"\xff\xff\xff\xff\xff\xff\xff\xff\xff").is_err());
    // A vector claiming 2^60 elements must be refused by the limit, not allocated.
    let mut bomb = encode(&1u16);
    bomb.extend(encode(&ClientId(1)));
    bomb.push(3); // RequestBody::Step
    bomb.extend(encode(&EnvId(1)));
    bomb.push(0); // seq
    bomb.push(253);
    bomb.extend((1u64 << 60).to_le_bytes());
    assert!(decode::<Request>(&bomb).is_err());
}

#[test]
fn the_byte_layout_is_what_docs_protocol_md_says() {
    // Request { version: 1, client: ClientId(300), body: Close { env: EnvId(2) } }:
    // version varint 1 -> [1]; client u128 300 -> 251 marker + u16 LE [251, 44, 1];
    // body variant index 8 (Close, the ninth variant) -> [8]; env u128 2 -> [2].
    let bytes = encode(&Request { version: 1, client: ClientId(300), body: RequestBody::Close { env: EnvId(2) } });
    assert_eq!(bytes, [1, 251, 44, 1, 8, 2]);
    // Action::Continuous([1.0, -2.0]): variant 1, then two f32 LE, no length.
    let mut expected = vec![1u8];
    expected.extend(1.0f32.to_le_bytes());
    expected.extend((-2.0f32).to_le_bytes());
    assert_eq!(encode(&Action::Continuous([1.0, -2.0])), expected);
    // Option<u64>: Some(70000) -> [1, 252, u32 LE]; strings: length varint then UTF-8.
    assert_eq!(encode(&Some(70000u64)), [1, 252, 0x70, 0x11, 0x01, 0x00]);
    assert_eq!(encode(&"ab".to_string()), [2, b'a', b'b']);
    // Signed integers zigzag: -3 -> 5.
    assert_eq!(encode(&-3i64), [5]);
}

#[test]
fn spaces_check_actions_and_observations() {
    let discrete = Space::Discrete { n: 5, start: 0 };
    assert!(discrete.contains_action(&Action::Meta(4)).is_ok());
    assert!(discrete.contains_action(&Action::Meta(5)).unwrap_err().contains("outside Discrete(5)"));
    assert!(discrete.contains_action(&Action::Continuous([0.0, 0.0])).is_err());
    let boxed = Space::Box { low: vec![-6.0, -4.0], high: vec![6.0, 4.0], shape: vec![2], dtype: DType::F32 };
    assert!(boxed.contains_action(&Action::Continuous([1.0, -4.0])).is_ok());
    assert!(boxed.contains_action(&Action::Continuous([f32::NAN, 0.0])).unwrap_err().contains("component 0"));
    assert!(boxed.contains_action(&Action::Continuous([0.0, 4.5])).unwrap_err().contains("outside [-4, 4]"));
    let unit = Space::Box { low: vec![-1.0; 4], high: vec![1.0; 4], shape: vec![2, 2], dtype: DType::F32 };
    let inside = Tensor::new(vec![2, 2], TensorData::F32(vec![0.0, 1.0, -1.0, 0.5])).unwrap();
    let outside = Tensor::new(vec![2, 2], TensorData::F32(vec![0.0, 1.5, -1.0, 0.5])).unwrap();
    let wrong_type = Tensor::new(vec![2, 2], TensorData::U8(vec![0; 4])).unwrap();
    assert!(unit.contains_tensor(&inside) && !unit.contains_tensor(&outside) && !unit.contains_tensor(&wrong_type));
    assert!(Tensor::new(vec![3], TensorData::F32(vec![0.0; 2])).is_none());
}

#[test]
fn ids_print_and_parse_as_32_hex_digits() {
    let id = EnvId(0xabc);
    assert_eq!(id.to_string(), "00000000000000000000000000000abc");
    assert_eq!(id.to_string().parse::<EnvId>().unwrap(), id);
    assert!("xyz".parse::<ClientId>().is_err());
}

#[test]
fn error_codes_have_stable_numbers() {
    assert_eq!(ErrorCode::MalformedRequest.as_u16(), 0);
    assert_eq!(ErrorCode::AgentNotLive.as_u16(), 14);
    assert_eq!(encode(&ErrorCode::TooManyEnvs), [11]);
}
