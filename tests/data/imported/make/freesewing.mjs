// Drafts FreeSewing designs for two measurement sets and renders each to SVG
// (the fixtures under tests/data/imported/freesewing/), run by make.sh (the test set-up and the remake).
//   node freesewing.mjs OUTDIR   (with package.json's packages installed: npm ci)
import { writeFileSync, mkdirSync } from 'node:fs'
import { Penelope } from '@freesewing/penelope'
import { Titan } from '@freesewing/titan'
import { Aaron } from '@freesewing/aaron'
import { Teagan } from '@freesewing/teagan'
import { cisFemaleAdult34, cisFemaleAdult42, cisMaleAdult38, cisMaleAdult46 } from '@freesewing/models'

const out = process.argv[2] || 'out'
mkdirSync(out, { recursive: true })
const designs = { penelope: Penelope, titan: Titan, aaron: Aaron, teagan: Teagan }
const sets = {
  penelope: { cisFemaleAdult34, cisFemaleAdult42 },
  titan: { cisMaleAdult38, cisMaleAdult46 },
  aaron: { cisMaleAdult38, cisMaleAdult46 },
  teagan: { cisFemaleAdult34, cisFemaleAdult42 },
}
for (const [name, Design] of Object.entries(designs)) {
  for (const [setName, measurements] of Object.entries(sets[name])) {
    // complete: the seam allowance is drawn too (the importer must tell it from the seam line)
    const pattern = new Design({ measurements, sa: 10, complete: true, paperless: false })
    pattern.draft()
    const svg = pattern.render()
    const file = `${out}/${name}_${setName}.svg`
    writeFileSync(file, svg)
    writeFileSync(`${out}/${setName}.json`, JSON.stringify(measurements, null, 1))
    const logs = pattern.store.logs || {}
    console.log(file, svg.length, 'bytes', (logs.error || []).length, 'errors')
  }
}
