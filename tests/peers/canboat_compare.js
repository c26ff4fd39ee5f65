// Decodes NMEA 2000 logs with canboatjs (npm @canboat/canboatjs, an
// implementation independent of the twin's) and checks that the same
// messages carried in other layouts decode to the same fields.
//
//   node tests/peers/canboat_compare.js REFERENCE OTHER...
//   node tests/peers/canboat_compare.js --fast-pgns PGN...   (those sent as fast packets)
//
// REFERENCE is canboat FAST text; each OTHER the same messages as candump,
// Yacht Devices RAW or Actisense N2K ASCII lines (frames of fast packets
// split, as on a bus). Each file is read by a parser of its own. Every
// decoded message of OTHER must equal the REFERENCE's message at the same
// position: PGN, source, destination, priority and every field (but the
// fast-packet sequence number canboatjs adds when it joins frames). Prints one
// JSON line per file and exits 1 at the first difference.

'use strict'

const fs = require('fs')
const { FromPgn } = require('@canboat/canboatjs')

function decode(path) {
  const parser = new FromPgn({ useCamel: true, checkForInvalidFields: false })
  const messages = []
  let errors = 0
  parser.on('error', () => {
    errors += 1
  })
  for (const line of fs.readFileSync(path, 'utf8').split('\n')) {
    if (line.trim() === '' || line.startsWith('#')) continue
    const pgn = parser.parseString(line)
    if (pgn) {
      // The fast-packet sequence number canboatjs adds when it joins frames
      // is the transport's, not a field of the message.
      const { sequenceId, ...fields } = pgn.fields
      messages.push({
        pgn: pgn.pgn,
        src: pgn.src,
        dst: pgn.dst,
        prio: pgn.prio,
        fields
      })
    }
  }
  return { messages, errors }
}

if (process.argv[2] === '--fast-pgns') {
  // Which of the PGNs given canboat's database sends as fast packets.
  const { getPgn } = require('@canboat/canboatjs/dist/pgns')
  const fast = process.argv
    .slice(3)
    .map(Number)
    .filter((pgn) => (getPgn(pgn) || []).some((d) => d.Type === 'Fast'))
  console.log(JSON.stringify(fast))
  process.exit(0)
}

const [reference, ...others] = process.argv.slice(2)
const want = decode(reference)
console.log(JSON.stringify({ file: reference, messages: want.messages.length, errors: want.errors }))
for (const other of others) {
  const got = decode(other)
  console.log(JSON.stringify({ file: other, messages: got.messages.length, errors: got.errors }))
  if (got.messages.length !== want.messages.length) {
    console.error(`${other}: ${got.messages.length} messages, ${want.messages.length} in ${reference}`)
    process.exit(1)
  }
  for (let i = 0; i < want.messages.length; i++) {
    const a = JSON.stringify(want.messages[i])
    const b = JSON.stringify(got.messages[i])
    if (a !== b) {
      console.error(`${other}: message ${i} differs\n  ${reference}: ${a}\n  ${other}: ${b}`)
      process.exit(1)
    }
  }
}
